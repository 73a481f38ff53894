// Perception benchmarks: one 640x480 frame of the tabletop scene (reference, block, target and end-effector
// tags): detection + pose estimation + state update, its parts, and rendering the frame.
#include <benchmark/benchmark.h>

#include <opencv2/core/utility.hpp>

#include "envs/perception/colour_tracker.h"
#include "envs/perception/perception_pipeline.h"
#include "envs/perception/synthetic_camera.h"
#include "envs/perception/tabletop_scene.h"
#include "envs/perception/tag_config.h"

namespace {

using namespace hlt;

// "One core": OpenCV would otherwise spread colour conversion, resizing and blurs over its thread pool.
const int kSingleThreaded = (cv::setNumThreads(1), 0);

TagConfig sawyer_tags() {
  return TagConfig::parse(
      "family: tag36h11\ntags:\n"
      "  - {id: 0, name: table, size: 0.048, table_pose: [0.0, 0.0, 0.0, 0.0]}\n"
      "  - {id: 1, name: block, size: 0.033, object_offset: [0.0, 0.0, -0.025]}\n"
      "  - {id: 2, name: target, size: 0.048, object_offset: [0.0, 0.0, -0.0015]}\n"
      "  - {id: 3, name: end_effector, size: 0.033, object_offset: [0.0, 0.0, -0.10]}\n",
      "bench");
}

CameraModel camera() {
  CameraModel c;
  c.set_world_from_camera(TabletopScene::default_camera_pose());
  return c;
}

cv::Mat frame(double noise) {
  const TabletopScene scene(sawyer_tags());
  ImageEffects e;
  e.noise_sigma = noise;
  e.seed = 1;
  return SyntheticCamera(camera()).render(scene.quads(TabletopScene::example_poses()), e);
}

// The whole per-frame cost: detection, pose estimation (with corner refinement) and the state update.
void PerceptionPipelineFrame(benchmark::State& state, double decimate) {
  const cv::Mat img = frame(2.0);
  PerceptionOptions o;
  o.detector.quad_decimate = decimate;
  PerceptionPipeline pipeline(camera(), sawyer_tags(), o);
  double t = 0;
  size_t tags = 0;
  for (auto _ : state) {
    const FrameResult& r = pipeline.process(img, t);
    t += 0.1;
    tags = r.detections.tags.size();
    benchmark::DoNotOptimize(r.state.object("block").table_from_object);
  }
  state.counters["tags"] = static_cast<double>(tags);
}
// quad_decimate 1.5 is the default; 1.0 and 2.0 bracket it.
BENCHMARK_CAPTURE(PerceptionPipelineFrame, decimate_1_0, 1.0)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(PerceptionPipelineFrame, decimate_1_5, 1.5)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(PerceptionPipelineFrame, decimate_2_0, 2.0)->Unit(benchmark::kMillisecond);

void PerceptionDetectOnly(benchmark::State& state) {
  const cv::Mat img = frame(2.0);
  TagDetectorOptions o;
  o.refine_corners = state.range(0) != 0;
  TagDetector detector(camera(), sawyer_tags(), o);
  for (auto _ : state)
    benchmark::DoNotOptimize(detector.detect(img));
}
BENCHMARK(PerceptionDetectOnly)->Arg(0)->Arg(1)->ArgName("refine")->Unit(benchmark::kMillisecond);

void PerceptionColourTracker(benchmark::State& state) {
  const cv::Mat img = frame(2.0);
  const ColourTracker tracker(camera());
  const Eigen::Isometry3d table_from_camera = camera().world_from_camera();
  for (auto _ : state)
    benchmark::DoNotOptimize(tracker.locate(tracker.detect(img), table_from_camera));
}
BENCHMARK(PerceptionColourTracker)->Unit(benchmark::kMillisecond);

// Rendering one frame of the tabletop scene: everything, and with the static table drawn once (the
// simulated tasks' case: only the objects move).
void PerceptionRenderFrame(benchmark::State& state) {
  const TabletopScene scene(sawyer_tags());
  SyntheticCamera renderer(camera());
  const bool cached = state.range(0) != 0;
  if (cached) renderer.set_static_quads(scene.static_quads());
  const TabletopPoses poses = TabletopScene::example_poses();
  ImageEffects e;
  e.noise_sigma = 2.0;
  for (auto _ : state) {
    ++e.seed;
    benchmark::DoNotOptimize(renderer.render(cached ? scene.object_quads(poses) : scene.quads(poses), e));
  }
}
BENCHMARK(PerceptionRenderFrame)->Arg(0)->Arg(1)->ArgName("static_cached")->Unit(benchmark::kMillisecond);

}  // namespace
