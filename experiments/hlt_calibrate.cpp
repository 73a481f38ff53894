// hlt_calibrate: camera intrinsics from a folder of checkerboard photos (OpenCV's chessboard detector and
// calibrateCamera). Prints the RMS reprojection error and the per-view errors, and writes the calibration as
// OpenCV FileStorage YAML for hlt_perceive (--calibration) and the robot tasks.
//
//   hlt_calibrate --images calib/ --cols 9 --rows 6 --square 0.025 --out camera.yaml
//   hlt_calibrate --render-demo demo/ ...   # write synthetic views of a known camera first, to try it out
#include <algorithm>
#include <cstdio>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "envs/perception/checkerboard_calibrator.h"
#include "envs/perception/frame_source.h"
#include "envs/perception/synthetic_camera.h"
#include "envs/perception/tabletop_scene.h"
#include "experiments/cli_checks.h"
#include "hlt/util/error.h"
#include "hlt/util/files.h"
#include "hlt/util/main_guard.h"

namespace {

// Twelve views of the board by a known camera, so the tool can be tried (and checked) without a camera.
void render_demo(const std::string& dir, cv::Size inner, double square) {
  hlt::ensure_writable_directory(dir);
  const hlt::CameraModel truth(640, 480, 612.0, 604.0, 326.0, 236.0, {-0.12, 0.04, 0.0, 0.0, 0.0});
  const hlt::SyntheticCamera renderer(truth);
  // Distances chosen so the board fills about two thirds of the image, whatever its size.
  const double scale = (std::max(inner.width, inner.height) + 3) * square / 0.33;
  int i = 0;
  for (const Eigen::Isometry3d& pose : hlt::TabletopScene::checkerboard_calibration_poses(scale)) {
    hlt::ImageEffects e;
    e.noise_sigma = 1.0;
    e.seed = static_cast<uint64_t>(i);
    const cv::Mat img = renderer.render({hlt::TabletopScene::checkerboard_quad(inner, square, pose)},
                                        Eigen::Isometry3d::Identity(), e);
    const std::string path = fmt::format("{}/view_{:02d}.png", dir, i++);
    hlt::check(cv::imwrite(path, img), "cannot write {}", path);
  }
  std::printf("wrote %d synthetic views to %s; true fx %.2f fy %.2f cx %.2f cy %.2f k1 %.3f k2 %.3f\n", i,
              dir.c_str(), truth.fx(), truth.fy(), truth.cx(), truth.cy(), truth.distortion()[0],
              truth.distortion()[1]);
}

}  // namespace

int run_tool(int argc, char** argv) {
  CLI::App app{"Estimate camera intrinsics from checkerboard images and write an OpenCV calibration YAML."};
  std::string images, out, demo;
  int cols = 0, rows = 0;
  double square = 0;
  bool k3 = false, zero_tangent = false, rational = false;
  app.add_option("--images", images, "folder of checkerboard images (png, jpg, bmp, tif)");
  app.add_option("--cols", cols, "inner corners per row (squares per row minus one)")
      ->required()
      ->check(CLI::Range(2, 100));
  app.add_option("--rows", rows, "inner corners per column (squares per column minus one)")
      ->required()
      ->check(CLI::Range(2, 100));
  app.add_option("--square", square, "edge of one square, metres")->required()->check(CLI::PositiveNumber);
  app.add_option("--out", out, "calibration YAML to write");
  app.add_flag("--k3", k3, "also estimate the radial term k3 (off by default: it overfits ordinary lenses)");
  app.add_flag("--zero-tangent", zero_tangent, "assume no tangential distortion (p1 = p2 = 0)");
  app.add_flag("--rational", rational, "8-coefficient rational model (wide-angle lenses)");
  app.add_option("--render-demo", demo, "write synthetic views of a known camera into this folder and exit");
  if (const std::optional<int> code = hlt::parse_command_line(app, argc, argv)) return *code;
  hlt::check_finite_flags(app);
  // Errors go to guarded_main: exit 2 for bad input, 3 out of memory, one line naming the tool once.
  const cv::Size inner(cols, rows);
  if (!demo.empty()) {
    render_demo(demo, inner, square);
    return 0;
  }
  hlt::check(!images.empty(), "--images is required (or --render-demo)");
  hlt::check(!out.empty(), "--out is required");
  hlt::CheckerboardCalibrator calibrator(inner, square);
  for (const std::string& path : hlt::FrameSource::image_files(images)) {
    const cv::Mat img = cv::imread(path, cv::IMREAD_COLOR);
    hlt::check(!img.empty(), "cannot read image {}", path);
    const bool found = calibrator.add_image(img, path);
    std::printf("%-50s %s\n", path.c_str(), found ? "board found" : "no board: skipped");
  }
  int flags = 0;
  if (!k3 && !rational) flags |= cv::CALIB_FIX_K3;
  if (zero_tangent) flags |= cv::CALIB_ZERO_TANGENT_DIST;
  if (rational) flags |= cv::CALIB_RATIONAL_MODEL;
  const hlt::CalibrationResult r = calibrator.calibrate(flags);
  std::printf("\n%zu views used, %zu rejected\n", r.used.size(), r.rejected.size());
  for (size_t i = 0; i < r.used.size(); ++i)
    std::printf("  %-50s reprojection RMS %.3f px\n", r.used[i].c_str(), r.per_view_rms[i]);
  const hlt::CameraModel& c = r.camera;
  std::printf("\nRMS reprojection error: %.4f px\n", r.rms);
  std::printf("fx %.3f  fy %.3f  cx %.3f  cy %.3f\n", c.fx(), c.fy(), c.cx(), c.cy());
  std::string d;
  for (double v : c.distortion())
    d += fmt::format(" {:.5f}", v);
  std::printf("distortion:%s\n", d.c_str());
  c.save(out, r.rms);
  std::printf("wrote %s\n", out.c_str());
  return 0;
}

int main(int argc, char** argv) {
  return hlt::guarded_main("hlt_calibrate", [&] { return run_tool(argc, argv); });
}
