// hlt_perceive: runs the perception pipeline (AprilTag detection and pose, colour tracking, state
// estimation) on a video file, an image folder or a live camera, and writes per-frame states and detections
// as CSV, optionally with an overlay video (tag outlines, axes, ids, object status).
//
//   hlt_perceive --input clip.mp4 --calibration camera.yaml --tags tags.yaml --csv states.csv --overlay
//   out.avi hlt_perceive --input camera:0 --calibration camera.yaml --tags tags.yaml --csv live.csv   #
//   Ctrl-C stops hlt_perceive --input synthetic:60 --tags tags.yaml --csv demo.csv   # a rendered push, no
//   camera needed
#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <exception>
#include <fstream>
#include <iterator>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "envs/perception/frame_source.h"
#include "envs/perception/overlay.h"
#include "envs/perception/perception_pipeline.h"
#include "envs/perception/pose_math.h"
#include "envs/perception/synthetic_camera.h"
#include "envs/perception/tabletop_scene.h"
#include "experiments/cli_checks.h"
#include "hlt/util/error.h"
#include "hlt/util/files.h"
#include "hlt/util/main_guard.h"

namespace {

std::atomic<bool> g_stop{false};
void on_signal(int) {
  g_stop = true;
}

// A scripted push rendered by the synthetic camera: the end-effector first sweeps past the front of the block
// (hiding its tag for a few frames, when colour tracking takes over), goes round behind it, comes down at its
// left face and pushes it 10 cm along x.
class SyntheticEpisode {
 public:
  SyntheticEpisode(const hlt::CameraModel& camera, const hlt::TagConfig& tags, int frames, double fps)
      : scene_(tags), renderer_(camera), frames_(frames), fps_(fps) {
    renderer_.set_static_quads(scene_.static_quads());
  }
  bool read(cv::Mat& frame, double& time) {
    if (i_ >= frames_) return false;
    const double u = frames_ > 1 ? static_cast<double>(i_) / (frames_ - 1) : 0.0;  // 0..1 through the episode
    struct Waypoint {
      double u, x, y, z;
    };
    static const Waypoint path[] = {{0.0, 0.09, -0.015, 0.07}, {0.35, 0.34, -0.015, 0.07},
                                    {0.45, 0.34, 0.13, 0.07},  {0.6, 0.15, 0.13, 0.07},
                                    {0.7, 0.15, 0.05, 0.01},   {1.0, 0.25, 0.05, 0.01}};
    size_t k = 0;
    while (k + 2 < std::size(path) && u > path[k + 1].u)
      ++k;
    const Waypoint &a = path[k], &b = path[k + 1];
    const double f = std::clamp((u - a.u) / (b.u - a.u), 0.0, 1.0);
    hlt::TabletopPoses p = hlt::TabletopScene::example_poses();
    const double ex = a.x + f * (b.x - a.x), ey = a.y + f * (b.y - a.y), ez = a.z + f * (b.z - a.z);
    p.end_effector = hlt::pose_from_xyz_rpy(ex, ey, ez, 0, 0, 0);
    const double push = u > 0.7 ? ex - 0.15 : 0.0;  // the block moves with the end-effector once in contact
    p.block = hlt::pose_from_xyz_rpy(0.20 + push, 0.05, 0.025, 0, 0, 0);
    hlt::ImageEffects e;
    e.noise_sigma = 2.0;
    e.seed = static_cast<uint64_t>(i_);
    frame = renderer_.render(scene_.object_quads(p), e);
    time = i_ / fps_;
    ++i_;
    return true;
  }

 private:
  hlt::TabletopScene scene_;
  hlt::SyntheticCamera renderer_;
  int frames_, i_ = 0;
  double fps_;
};

cv::Scalar parse_hsv(const std::string& text, const char* flag) {
  int h, s, v;
  char tail;
  hlt::check(std::sscanf(text.c_str(), "%d,%d,%d%c", &h, &s, &v, &tail) == 3,
             "{} expects H,S,V (OpenCV ranges: H 0-180, S and V 0-255), got '{}'", flag, text);
  return cv::Scalar(h, s, v);
}

}  // namespace

int run_tool(int argc, char** argv) {
  CLI::App app{"Detect AprilTags, track the coloured block and estimate the pushing task's state per frame."};
  std::string input, calibration, tags_path, csv = "perception_states.csv", detections_csv, overlay,
                                             save_frames;
  std::string hsv_low, hsv_high;
  int max_frames = 0;
  double fps = 10.0;
  hlt::PerceptionOptions o;
  bool no_refine = false, no_colour = false, quiet = false;
  app.add_option("--input", input,
                 "video file, image folder, camera:N (live), or synthetic:N (N rendered frames)")
      ->required();
  app.add_option("--calibration", calibration,
                 "camera calibration YAML (OpenCV/ROS); optional for synthetic input");
  app.add_option("--tags", tags_path, "tag configuration YAML (ids, names, sizes, reference tag)")
      ->required();
  app.add_option("--csv", csv, "per-frame states CSV")->capture_default_str();
  app.add_option("--detections-csv", detections_csv, "per-detection CSV (default: <csv>_detections.csv)");
  app.add_option("--overlay", overlay, "write an overlay video here (.avi, MJPG)");
  app.add_option("--save-frames", save_frames, "also save the input frames as PNGs into this folder");
  app.add_option("--max-frames", max_frames, "stop after this many frames (0: all)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--fps", fps, "frame rate of image folders and synthetic input")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--decimate", o.detector.quad_decimate,
                 "libapriltag quad_decimate (>1 faster, loses small tags)")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 8.0));
  app.add_option("--threads", o.detector.threads, "libapriltag threads")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  app.add_flag("--no-refine", no_refine, "keep libapriltag's corners (no sub-pixel corner refinement)");
  app.add_flag("--no-colour", no_colour, "no colour tracking when the block's tag is missing");
  app.add_option("--hsv-low", hsv_low, "colour tracker lower HSV bound H,S,V (default 95,110,35: blue)");
  app.add_option("--hsv-high", hsv_high, "colour tracker upper HSV bound H,S,V (default 125,255,255)");
  app.add_option("--block-size", o.colour.block_size,
                 "block edge (m): colour blobs much smaller than a whole block are ignored; 0: keep all")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--plane-height", o.colour.plane_height, "height of the block's centre above the table (m)")
      ->capture_default_str();
  app.add_option("--position-gain", o.estimator.position_gain, "filter weight of a new position (0-1]")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 1.0));
  app.add_option("--rotation-gain", o.estimator.rotation_gain, "filter weight of a new orientation (0-1]")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 1.0));
  app.add_option("--max-misses", o.estimator.max_misses,
                 "frames an object may be missed before it is invalid")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--quiet", quiet, "no progress line every 25 frames");
  if (const std::optional<int> code = hlt::parse_command_line(app, argc, argv)) return *code;
  hlt::check_finite_flags(app);
  // Errors go to guarded_main: exit 2 for bad input, 3 out of memory, one line naming the tool once.
  o.detector.refine_corners = !no_refine;
  o.colour_fallback = !no_colour;
  if (!hsv_low.empty()) o.colour.hsv_low = parse_hsv(hsv_low, "--hsv-low");
  if (!hsv_high.empty()) o.colour.hsv_high = parse_hsv(hsv_high, "--hsv-high");
  const hlt::TagConfig tags = hlt::TagConfig::load(tags_path);
  const bool synthetic = input.rfind("synthetic", 0) == 0;
  hlt::CameraModel camera;
  if (!calibration.empty()) {
    camera = hlt::CameraModel::load(calibration);
  } else {
    hlt::check(synthetic, "--calibration is required for real input (hlt_calibrate writes one)");
  }
  if (synthetic && !camera.has_extrinsics())
    camera.set_world_from_camera(hlt::TabletopScene::default_camera_pose());

  std::unique_ptr<hlt::FrameSource> source;
  std::unique_ptr<SyntheticEpisode> episode;
  std::string description;
  if (synthetic) {
    int n = 60;
    if (input.size() > 9) {
      hlt::check(input[9] == ':', "synthetic input is 'synthetic' or 'synthetic:N', got '{}'", input);
      try {
        n = std::stoi(input.substr(10));
      } catch (const std::exception&) {
        n = -1;
      }
      hlt::check(n > 0, "synthetic:N needs a positive frame count, got '{}'", input);
    }
    episode = std::make_unique<SyntheticEpisode>(camera, tags, n, fps);
    description = fmt::format("{} synthetic frames", n);
  } else {
    source = std::make_unique<hlt::FrameSource>(input, fps, camera.size());
    description = source->description();
  }
  hlt::PerceptionPipeline pipeline(camera, tags, o);

  if (detections_csv.empty()) {
    const std::string stem =
        csv.size() > 4 && csv.substr(csv.size() - 4) == ".csv" ? csv.substr(0, csv.size() - 4) : csv;
    detections_csv = stem + "_detections.csv";
  }
  // Rows are flushed as they are written, so a live run stopped any way keeps what it saw. The files are
  // opened at the first frame read, so an input that yields nothing leaves existing CSVs alone, and every
  // write is checked: a full disk stops the run instead of dropping rows.
  std::ofstream states, detections;
  auto open_csvs = [&] {
    states.open(csv);
    detections.open(detections_csv);
    hlt::check(states.good(), "cannot write {}", csv);
    hlt::check(detections.good(), "cannot write {}", detections_csv);
    states << hlt::PerceptionPipeline::states_csv_header() << "\n";
    detections << hlt::PerceptionPipeline::detections_csv_header() << "\n";
  };
  if (!save_frames.empty()) hlt::ensure_writable_directory(save_frames);
  cv::VideoWriter writer;

  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::fprintf(stderr, "hlt_perceive: %s, camera %dx%d, %zu configured tags\n", description.c_str(),
               camera.width(), camera.height(), tags.tags().size());
  cv::Mat frame;
  double t = 0, sum_ms = 0;
  int64_t n = 0, valid = 0;
  std::vector<double> ms;
  while (!g_stop && (max_frames == 0 || n < max_frames)) {
    const bool got = episode ? episode->read(frame, t) : source->read(frame, t);
    if (!got) break;
    if (!save_frames.empty())
      hlt::check(cv::imwrite(fmt::format("{}/frame_{:06d}.png", save_frames, n), frame),
                 "cannot write frames to {}", save_frames);
    const hlt::FrameResult& r = pipeline.process(frame, t);
    if (n == 0) open_csvs();
    states << hlt::PerceptionPipeline::states_csv_row(r) << "\n" << std::flush;
    detections << hlt::PerceptionPipeline::detections_csv_rows(r) << std::flush;
    hlt::check(states.good() && detections.good(),
               "writing {} or {} failed at frame {} (disk full?); the rows before it are kept", csv,
               detections_csv, n);
    if (!overlay.empty()) {
      cv::Mat shown = frame.clone();
      hlt::draw_overlay(shown, camera, r);
      if (!writer.isOpened()) {
        writer.open(overlay, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), fps, shown.size());
        hlt::check(writer.isOpened(), "cannot write overlay video {}", overlay);
      }
      writer.write(shown);
    }
    ++n;
    valid += r.state.valid() ? 1 : 0;
    sum_ms += r.total_ms;
    ms.push_back(r.total_ms);
    if (!quiet && n % 25 == 0)
      std::fprintf(stderr, "  frame %lld  t %.2fs  tags %zu  %.1f ms\n", static_cast<long long>(n), t,
                   r.detections.tags.size(), r.total_ms);
  }
  hlt::check(n > 0, "no frames read from {}", input);
  std::sort(ms.begin(), ms.end());
  std::fprintf(
      stderr, "hlt_perceive: %lld frames, %lld with a valid state, %.2f ms mean / %.2f ms median per frame\n",
      static_cast<long long>(n), static_cast<long long>(valid), sum_ms / n, ms[ms.size() / 2]);
  std::fprintf(stderr, "  states: %s\n  detections: %s\n", csv.c_str(), detections_csv.c_str());
  if (!overlay.empty()) std::fprintf(stderr, "  overlay: %s\n", overlay.c_str());
  return 0;
}

int main(int argc, char** argv) {
  return hlt::guarded_main("hlt_perceive", [&] { return run_tool(argc, argv); });
}
