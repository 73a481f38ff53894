// hlt_perception_eval: measures the perception pipeline's accuracy on images rendered at known poses and
// prints the tables of docs/PERCEPTION.md (tag pose error by condition and distance, colour tracking error,
// calibration error). Everything is seeded: the same build prints the same numbers.
//
//   hlt_perception_eval [--seeds 3]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <opencv2/calib3d.hpp>

#include "envs/perception/checkerboard_calibrator.h"
#include "envs/perception/colour_tracker.h"
#include "envs/perception/pose_math.h"
#include "envs/perception/synthetic_camera.h"
#include "envs/perception/tabletop_scene.h"
#include "envs/perception/tag_detector.h"
#include "experiments/cli_checks.h"
#include "hlt/util/error.h"
#include "hlt/util/main_guard.h"

namespace {

using namespace hlt;

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}
double maximum(const std::vector<double>& v) {
  return v.empty() ? NAN : *std::max_element(v.begin(), v.end());
}

struct Condition {
  std::string name;
  ImageEffects effects;
  CameraModel camera;
  bool refine = true;
  bool seeded = false;  // has noise: repeat with several seeds
};

Eigen::Isometry3d tag_in_front(double distance, double tilt_deg, double yaw, double dx, double dy) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::Vector3d(1, -1, -1).asDiagonal();
  return Eigen::Translation3d(dx, dy, distance) * pose * Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
         Eigen::AngleAxisd(tilt_deg * M_PI / 180.0, Eigen::Vector3d::UnitX());
}

void tag_table(const std::vector<Condition>& conditions, int seeds, double decimate) {
  const TagConfig config = TagConfig::parse(
      "family: tag36h11\ntags:\n  - {id: 1, name: small, size: 0.033}\n  - {id: 2, name: large, size: "
      "0.048}\n",
      "eval");
  const TagFamily family("tag36h11");
  std::printf("### Tag pose error (quad_decimate %.1f)\n\n", decimate);
  std::printf(
      "Tags of 0.033 and 0.048 m, frontal and tilted by 20 and 40 degrees, two in-plane angles, two "
      "positions in the image; %d noise seeds where noise is added. Position error is the distance between "
      "estimated and true tag centre; rotation error the angle of the relative rotation.\n\n",
      seeds);
  std::printf(
      "| condition | distance (m) | detected | position median (mm) | position max (mm) | max / distance | "
      "rotation median (deg) | rotation max, frontal (deg) | rotation max, tilted 20-40 (deg) |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|\n");
  for (const Condition& c : conditions) {
    const SyntheticCamera renderer(c.camera);
    TagDetectorOptions o;
    o.refine_corners = c.refine;
    o.quad_decimate = decimate;
    TagDetector detector(c.camera, config, o);
    for (double distance : {0.3, 0.5, 0.8}) {
      std::vector<double> pos, rot, rot_frontal, rot_tilted;
      int cases = 0, found = 0;
      uint64_t seed = 100;
      for (int s = 0; s < (c.seeded ? seeds : 1); ++s)
        for (double size : {0.033, 0.048})
          for (double tilt : {0.0, 20.0, 40.0})
            for (double yaw : {0.0, 0.7})
              for (const auto& [dx, dy] : {std::pair{0.03, -0.02}, std::pair{-0.06, 0.05}}) {
                const int id = size < 0.04 ? 1 : 2;
                const Eigen::Isometry3d truth = tag_in_front(distance, tilt, yaw, dx, dy);
                TexturedQuad q = TabletopScene::tag_quad(family, id, size, truth);
                q.lit = false;
                ImageEffects e = c.effects;
                e.seed = seed++;
                const TagDetectionResult r =
                    detector.detect(renderer.render({q}, Eigen::Isometry3d::Identity(), e));
                ++cases;
                if (r.tags.size() != 1 || r.tags[0].id != id) continue;
                ++found;
                const TagDetection& d = r.tags[0];
                pos.push_back((d.camera_from_tag.translation() - truth.translation()).norm());
                const double dr =
                    rotation_angle_between(d.camera_from_tag.linear(), truth.linear()) * 180 / M_PI;
                rot.push_back(dr);
                (tilt == 0.0 ? rot_frontal : rot_tilted).push_back(dr);
              }
      std::printf("| %s | %.1f | %d/%d | %.2f | %.2f | %.2f%% | %.2f | %.2f | %.2f |\n", c.name.c_str(),
                  distance, found, cases, 1000 * median(pos), 1000 * maximum(pos),
                  100 * maximum(pos) / distance, median(rot), maximum(rot_frontal), maximum(rot_tilted));
    }
  }
  std::printf("\n");
}

void colour_table() {
  const TagConfig tags = TagConfig::parse(
      "family: tag36h11\ntags:\n  - {id: 0, name: table, size: 0.048, table_pose: [0, 0, 0, 0]}\n"
      "  - {id: 1, name: block, size: 0.033, object_offset: [0, 0, -0.025]}\n",
      "eval");
  CameraModel camera;
  camera.set_world_from_camera(TabletopScene::default_camera_pose());
  TabletopLayout layout;
  layout.show_end_effector = false;
  layout.show_target = false;
  const TabletopScene scene(tags, layout);
  SyntheticCamera renderer(camera);
  renderer.set_static_quads(scene.static_quads());
  const ColourTracker tracker(camera);
  std::printf("### Colour tracking error on the table plane\n\n");
  std::printf(
      "The 5 cm blue block (with its tag on top) at 5 x 5 positions over x in [0, 0.4] m, y in [-0.1, 0.3] m "
      "and yaw 0, 0.4 and 0.8 rad, seen by the default camera (0.7-0.95 m away, looking down at about 50 "
      "degrees); error of the block centre in the table plane.\n\n");
  std::printf("| image | blocks found | median (mm) | max (mm) |\n|---|---|---|---|\n");
  for (const auto& [name, noise, blur] : {std::tuple{"clean", 0.0, 0.0}, std::tuple{"noise 3", 3.0, 0.0},
                                          std::tuple{"blur 1.0 px + noise 2", 2.0, 1.0}}) {
    std::vector<double> err;
    int cases = 0;
    uint64_t seed = 1;
    for (int ix = 0; ix < 5; ++ix)
      for (int iy = 0; iy < 5; ++iy)
        for (double yaw : {0.0, 0.4, 0.8}) {
          TabletopPoses poses;
          poses.block = pose_from_xyz_rpy(0.1 * ix, -0.1 + 0.1 * iy, 0.025, 0, 0, yaw);
          if (poses.block.translation().head<2>().norm() < 0.06) continue;  // on the reference tag
          ImageEffects e;
          e.noise_sigma = noise;
          e.blur_sigma = blur;
          e.seed = seed++;
          ++cases;
          const ColourBlob blob = tracker.detect(renderer.render(scene.object_quads(poses), e));
          const std::optional<Eigen::Vector3d> p = tracker.locate(blob, camera.world_from_camera());
          if (!p) continue;
          err.push_back((p->head<2>() - poses.block.translation().head<2>()).norm());
        }
    std::printf("| %s | %zu/%d | %.2f | %.2f |\n", name, err.size(), cases, 1000 * median(err),
                1000 * maximum(err));
  }
  std::printf("\n");
}

void calibration_table() {
  const CameraModel truth(640, 480, 612.0, 604.0, 326.0, 236.0, {-0.12, 0.04, 0.0, 0.0, 0.0});
  const SyntheticCamera renderer(truth);
  const cv::Size inner(8, 6);
  std::printf("### Calibration from rendered checkerboards\n\n");
  std::printf(
      "An 8x6-corner board of 3 cm squares in 12 views (0.45-0.55 m, tilted up to 30 degrees) by a camera "
      "with fx 612, fy 604, cx 326, cy 236, k1 -0.12, k2 0.04; k3 fixed at 0.\n\n");
  std::printf("| image noise | views used | RMS (px) | fx error | fy error | cx error | cy error | k1 |\n");
  std::printf("|---|---|---|---|---|---|---|---|\n");
  for (double noise : {0.0, 1.0, 3.0}) {
    CheckerboardCalibrator calibrator(inner, 0.03);
    int i = 0;
    for (const Eigen::Isometry3d& pose : TabletopScene::checkerboard_calibration_poses()) {
      ImageEffects e;
      e.noise_sigma = noise;
      e.seed = static_cast<uint64_t>(i);
      calibrator.add_image(renderer.render({TabletopScene::checkerboard_quad(inner, 0.03, pose)},
                                           Eigen::Isometry3d::Identity(), e),
                           std::to_string(i));
      ++i;
    }
    const CalibrationResult r = calibrator.calibrate(cv::CALIB_FIX_K3);
    auto rel = [](double a, double b) { return fmt::format("{:+.3f}%", 100 * (a - b) / b); };
    std::printf("| %.0f | %zu | %.3f | %s | %s | %s | %s | %.4f |\n", noise, r.used.size(), r.rms,
                rel(r.camera.fx(), truth.fx()).c_str(), rel(r.camera.fy(), truth.fy()).c_str(),
                rel(r.camera.cx(), truth.cx()).c_str(), rel(r.camera.cy(), truth.cy()).c_str(),
                r.camera.distortion()[0]);
  }
  std::printf("\n");
}

}  // namespace

int run_tool(int argc, char** argv) {
  CLI::App app{"Accuracy of tag poses, colour tracking and calibration on rendered images with known truth."};
  int seeds = 3;
  bool tags_only = false;
  double decimate = TagDetectorOptions().quad_decimate;
  app.add_option("--seeds", seeds, "noise seeds per noisy condition")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  app.add_flag("--tags-only", tags_only, "only the tag pose table");
  app.add_option("--decimate", decimate, "libapriltag quad_decimate")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 8.0));
  if (const std::optional<int> code = hlt::parse_command_line(app, argc, argv)) return *code;
  hlt::check_finite_flags(app);
  // Errors go to guarded_main: exit 2 for bad input, 3 out of memory, one line naming the tool once.
  std::vector<Condition> conditions;
  auto add = [&](std::string name, ImageEffects e, CameraModel cam = CameraModel(), bool refine = true) {
    conditions.push_back({std::move(name), e, std::move(cam), refine, e.noise_sigma > 0});
  };
  ImageEffects e;
  add("clean", e);
  add("clean, libapriltag corners only", e, CameraModel(), false);
  e.noise_sigma = 3.0;
  add("noise 3", e);
  e = {};
  e.blur_sigma = 0.6;
  add("blur 0.6 px", e);
  e.blur_sigma = 1.0;
  add("blur 1.0 px", e);
  e = {};
  e.gain = 0.45;
  e.noise_sigma = 2.0;
  add("dark (x0.45) + noise 2", e);
  e = {};
  e.blur_sigma = 0.6;
  e.noise_sigma = 2.0;
  add("blur 0.6 px + noise 2", e);
  add("lens distortion (k1 -0.2), clean", {},
      CameraModel(640, 480, 600, 600, 319.5, 239.5, {-0.2, 0.05, 0.0005, -0.0005, 0}));
  tag_table(conditions, seeds, decimate);
  if (!tags_only) {
    colour_table();
    calibration_table();
  }
  return 0;
}

int main(int argc, char** argv) {
  return hlt::guarded_main("hlt_perception_eval", [&] { return run_tool(argc, argv); });
}
