#include "envs/perception/colour_tracker.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "envs/perception/pose_math.h"
#include "envs/perception/tabletop_scene.h"
#include "perception_test_support.h"

namespace hlt {
namespace {

using test::error_of;

struct Rig {
  TagConfig tags = test::sawyer_tags();
  CameraModel camera;
  TabletopLayout layout;
  Rig() {
    camera.set_world_from_camera(TabletopScene::default_camera_pose());
    layout.show_end_effector = false;  // nothing in front of the block
  }
};

TEST(ColourTracker, LocatesTheBlockOnTheTableWithinFiveMillimetres) {
  Rig rig;
  const TabletopScene scene(rig.tags, rig.layout);
  SyntheticCamera renderer(rig.camera);
  renderer.set_static_quads(scene.static_quads());
  const ColourTracker tracker(rig.camera);
  double worst = 0;
  int n = 0;
  for (double x : {0.0, 0.2, 0.4})
    for (double y : {-0.1, 0.1, 0.3})
      for (double yaw : {0.0, 0.5}) {
        TabletopPoses poses = TabletopScene::example_poses();
        poses.block = pose_from_xyz_rpy(x, y, 0.025, 0, 0, yaw);
        poses.target = pose_from_xyz_rpy(0.6, 0.4, 0.0015, 0, 0, 0);  // out of the way
        ImageEffects e;
        e.noise_sigma = 2.0;
        e.seed = static_cast<uint64_t>(++n);
        const ColourBlob blob = tracker.detect(renderer.render(scene.object_quads(poses), e));
        ASSERT_TRUE(blob.found) << x << " " << y;
        const std::optional<Eigen::Vector3d> p = tracker.locate(blob, rig.camera.world_from_camera());
        ASSERT_TRUE(p.has_value());
        EXPECT_NEAR(p->z(), 0.025, 1e-9);
        worst = std::max(worst, (p->head<2>() - poses.block.translation().head<2>()).norm());
      }
  EXPECT_LT(worst, 0.005);
  RecordProperty("worst_error_m", std::to_string(worst));
}

TEST(ColourTracker, FindsNothingWithoutTheBlockAndHandlesRedHues) {
  Rig rig;
  rig.layout.show_block = false;
  const TabletopScene empty(rig.tags, rig.layout);
  const SyntheticCamera renderer(rig.camera);
  const ColourTracker tracker(rig.camera);
  const ColourBlob none = tracker.detect(renderer.render(empty.quads(TabletopScene::example_poses())));
  EXPECT_FALSE(none.found);
  EXPECT_FALSE(tracker.locate(none, rig.camera.world_from_camera()).has_value());

  // A red block needs a hue range that wraps through 0.
  rig.layout.show_block = true;
  rig.layout.block_colour = cv::Vec3b(40, 30, 200);
  const TabletopScene red(rig.tags, rig.layout);
  ColourTrackerOptions o;
  o.hsv_low = cv::Scalar(170, 110, 35);
  o.hsv_high = cv::Scalar(8, 255, 255);
  const ColourTracker red_tracker(rig.camera, o);
  const TabletopPoses poses = TabletopScene::example_poses();
  const ColourBlob blob = red_tracker.detect(renderer.render(red.quads(poses)));
  ASSERT_TRUE(blob.found);
  const Eigen::Vector3d p = *red_tracker.locate(blob, rig.camera.world_from_camera());
  EXPECT_LT((p.head<2>() - poses.block.translation().head<2>()).norm(), 0.005);
}

TEST(ColourTracker, RefusesAMostlyHiddenBlock) {
  Rig rig;
  rig.layout.show_end_effector = true;
  const TabletopScene scene(rig.tags, rig.layout);
  const SyntheticCamera renderer(rig.camera);
  const ColourTracker tracker(rig.camera);
  TabletopPoses poses = TabletopScene::example_poses();
  poses.block = pose_from_xyz_rpy(0.2, 0.05, 0.025, 0, 0, 0);
  // The end-effector hangs between the camera and the block: only a sliver of blue shows, whose centroid
  // is far from the block's; better no answer than that one.
  poses.end_effector = pose_from_xyz_rpy(0.2, -0.015, 0.07, 0, 0, 0);
  const ColourBlob hidden = tracker.detect(renderer.render(scene.quads(poses)));
  EXPECT_FALSE(tracker.locate(hidden, rig.camera.world_from_camera()).has_value());
  // Without the check the sliver gives a position, off by more than the tracker's usual error.
  ColourTrackerOptions o;
  o.block_size = 0;
  const ColourTracker unchecked(rig.camera, o);
  const std::optional<Eigen::Vector3d> p = unchecked.locate(hidden, rig.camera.world_from_camera());
  if (p) {
    EXPECT_GT((p->head<2>() - poses.block.translation().head<2>()).norm(), 0.005);
  }
  // Moved aside, the block is found again.
  poses.end_effector = pose_from_xyz_rpy(0.06, 0.02, 0.01, 0, 0, 0);
  const ColourBlob seen = tracker.detect(renderer.render(scene.quads(poses)));
  const std::optional<Eigen::Vector3d> q = tracker.locate(seen, rig.camera.world_from_camera());
  ASSERT_TRUE(q.has_value());
  EXPECT_LT((q->head<2>() - poses.block.translation().head<2>()).norm(), 0.005);
  EXPECT_NEAR(seen.area, tracker.expected_area(poses.block.translation(), rig.camera.world_from_camera()),
              0.25 * seen.area);
}

TEST(ColourTracker, BadInputsAreClearErrors) {
  const ColourTracker tracker{CameraModel()};
  EXPECT_NE(error_of([&] {
              tracker.detect(cv::Mat(480, 640, CV_8UC1, cv::Scalar(0)));
            }).find("colour tracking needs a BGR image (3 or 4 channels), got 1 channel(s)"),
            std::string::npos);
  EXPECT_NE(error_of([&] { tracker.detect(cv::Mat()); }).find("the image is empty"), std::string::npos);
  ColourTrackerOptions o;
  o.hsv_low = cv::Scalar(10, 200, 0);
  o.hsv_high = cv::Scalar(20, 100, 255);
  EXPECT_NE(error_of([&] { ColourTracker(CameraModel(), o); }).find("HSV channel 1 has low > high"),
            std::string::npos);
  Eigen::Isometry3d nan_pose = Eigen::Isometry3d::Identity();
  nan_pose(0, 3) = NAN;
  ColourBlob blob;
  blob.found = true;
  EXPECT_NE(error_of([&] { tracker.locate(blob, nan_pose); }).find("not finite"), std::string::npos);
}

}  // namespace
}  // namespace hlt
