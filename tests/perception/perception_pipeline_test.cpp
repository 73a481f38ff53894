#include "envs/perception/perception_pipeline.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "envs/perception/overlay.h"
#include "envs/perception/pose_math.h"
#include "envs/perception/tabletop_scene.h"
#include "perception_test_support.h"

namespace hlt {
namespace {

size_t columns(const std::string& line) {
  return std::count(line.begin(), line.end(), ',') + 1;
}

TEST(PerceptionPipeline, TracksAPushAndWritesConsistentCsv) {
  const TagConfig config = test::sawyer_tags();
  CameraModel camera = CameraModel::load(test::config_path("camera_640x480.yaml"));
  const TabletopScene scene(config);
  SyntheticCamera renderer(camera);
  renderer.set_static_quads(scene.static_quads());
  PerceptionPipeline pipeline(camera, config);
  TabletopPoses poses = TabletopScene::example_poses();
  for (int i = 0; i < 5; ++i) {
    // The end-effector, just touching the block's side, pushes it 1 cm per frame along x.
    poses.block = pose_from_xyz_rpy(0.20 + 0.01 * i, 0.05, 0.025, 0, 0, 0.0);
    poses.end_effector = pose_from_xyz_rpy(0.15 + 0.01 * i, 0.05, 0.01, 0, 0, 0.0);
    ImageEffects e;
    e.noise_sigma = 2.0;
    e.seed = static_cast<uint64_t>(i);
    const FrameResult& r = pipeline.process(renderer.render(scene.object_quads(poses), e), 0.2 * i);
    ASSERT_TRUE(r.state.valid()) << i;
    EXPECT_EQ(r.detections.tags.size(), 4u);
    EXPECT_FALSE(r.colour.has_value());  // colour tracking only runs when the block's tag is missing
    // Filtered estimates lag a moving object a little: within 1 cm at 1 cm per frame.
    EXPECT_LT((r.state.object("block").table_from_object.translation() - poses.block.translation()).norm(),
              0.01)
        << i;
    const std::string row = PerceptionPipeline::states_csv_row(r);
    EXPECT_EQ(columns(row), columns(PerceptionPipeline::states_csv_header()));
    const std::string rows = PerceptionPipeline::detections_csv_rows(r);
    EXPECT_EQ(std::count(rows.begin(), rows.end(), '\n'), 4);
    EXPECT_EQ(columns(rows.substr(0, rows.find('\n'))), columns(PerceptionPipeline::detections_csv_header()));
    cv::Mat overlay = renderer.render(scene.object_quads(poses));
    const cv::Mat before = overlay.clone();
    draw_overlay(overlay, camera, r);
    EXPECT_GT(cv::norm(overlay, before, cv::NORM_L1), 0.0);
  }
  // At rest, the filter converges onto the truth.
  for (int i = 5; i < 15; ++i)
    pipeline.process(renderer.render(scene.object_quads(poses)), 0.2 * i);
  EXPECT_LT(
      (pipeline.last().state.object("block").table_from_object.translation() - poses.block.translation())
          .norm(),
      0.001);
  const Eigen::VectorXd v = pipeline.last().state.vector();
  // The end-effector's origin is 10 cm below its tag, so a small tag rotation error moves it by millimetres.
  EXPECT_NEAR(v(0), 0.05, 0.003);
  EXPECT_NEAR(v(1), 0.0, 0.003);
}

}  // namespace
}  // namespace hlt
