#include "envs/perception/state_estimator.h"

#include <gtest/gtest.h>

#include <cmath>

#include "envs/perception/perception_pipeline.h"
#include "envs/perception/pose_math.h"
#include "envs/perception/tabletop_scene.h"
#include "perception_test_support.h"

namespace hlt {
namespace {

using test::error_of;

// Detections as a perfect detector would report them for objects at `poses`, seen by a camera at
// `table_from_camera`. Leave a name out of `visible` to hide that tag.
std::vector<TagDetection> perfect_detections(const TagConfig& config,
                                             const Eigen::Isometry3d& table_from_camera,
                                             const TabletopPoses& poses,
                                             const std::vector<std::string>& visible) {
  std::vector<TagDetection> out;
  const Eigen::Isometry3d camera_from_table = table_from_camera.inverse();
  for (const std::string& name : visible) {
    const TagSpec& spec = config.by_name(name);
    Eigen::Isometry3d table_from_tag;
    if (spec.table_from_tag) {
      table_from_tag = *spec.table_from_tag;
    } else {
      const Eigen::Isometry3d& object = name == "block"    ? poses.block
                                        : name == "target" ? poses.target
                                                           : poses.end_effector;
      table_from_tag = object * spec.tag_from_object.inverse();
    }
    TagDetection d;
    d.id = spec.id;
    d.name = spec.name;
    d.size = spec.size;
    d.camera_from_tag = camera_from_table * table_from_tag;
    out.push_back(d);
  }
  return out;
}

const std::vector<std::string> kAll = {"table", "block", "target", "end_effector"};

TEST(StateEstimator, ReportsTheTaskStateInTheTableFrame) {
  const TagConfig config = test::sawyer_tags();
  const Eigen::Isometry3d camera = TabletopScene::default_camera_pose();
  const TabletopPoses poses = TabletopScene::example_poses();
  StateEstimator estimator(config);
  const TaskState& s = estimator.update(0.0, perfect_detections(config, camera, poses, kAll));
  ASSERT_TRUE(s.valid());
  EXPECT_TRUE(s.table_from_camera.isApprox(camera, 1e-9));
  EXPECT_TRUE(s.object("block").table_from_object.isApprox(poses.block, 1e-9));
  EXPECT_TRUE(s.object("target").table_from_object.isApprox(poses.target, 1e-9));
  EXPECT_TRUE(s.object("end_effector").table_from_object.isApprox(poses.end_effector, 1e-9));
  const Eigen::VectorXd v = s.vector();
  ASSERT_EQ(v.size(), 6);
  EXPECT_NEAR(v(0), poses.block.translation().x() - poses.end_effector.translation().x(), 1e-9);
  EXPECT_NEAR(v(1), poses.block.translation().y() - poses.end_effector.translation().y(), 1e-9);
  EXPECT_NEAR(v(2), 0.3 - 0.1, 1e-9);  // example yaws: block 0.3, end-effector 0.1, target -0.2
  EXPECT_NEAR(v(3), poses.target.translation().x() - poses.block.translation().x(), 1e-9);
  EXPECT_NEAR(v(5), -0.2 - 0.3, 1e-9);
  EXPECT_EQ(s.object("block").source, EstimateSource::kTag);
  EXPECT_FALSE(s.object("block").stale);
}

TEST(StateEstimator, FiltersSmallChangesAndFollowsJumps) {
  const TagConfig config = test::sawyer_tags();
  const Eigen::Isometry3d camera = TabletopScene::default_camera_pose();
  TabletopPoses poses = TabletopScene::example_poses();
  StateEstimatorOptions o;
  o.position_gain = 0.5;
  StateEstimator estimator(config, o);
  estimator.update(0.0, perfect_detections(config, camera, poses, kAll));
  const Eigen::Vector3d before = poses.block.translation();
  poses.block.translation().x() += 0.004;  // a small step is smoothed: half of it at gain 0.5
  double x = estimator.update(0.1, perfect_detections(config, camera, poses, kAll))
                 .object("block")
                 .table_from_object.translation()
                 .x();
  EXPECT_NEAR(x, before.x() + 0.002, 1e-9);
  poses.block.translation().x() += 0.2;  // a jump (the block was moved by hand) is taken at once
  x = estimator.update(0.2, perfect_detections(config, camera, poses, kAll))
          .object("block")
          .table_from_object.translation()
          .x();
  EXPECT_NEAR(x, poses.block.translation().x(), 1e-9);
}

TEST(StateEstimator, MissedDetectionsHoldTheEstimateAndFlagItStale) {
  const TagConfig config = test::sawyer_tags();
  const Eigen::Isometry3d camera = TabletopScene::default_camera_pose();
  const TabletopPoses poses = TabletopScene::example_poses();
  StateEstimatorOptions o;
  o.max_misses = 5;
  o.max_age = 10.0;
  StateEstimator estimator(config, o);
  estimator.update(0.0, perfect_detections(config, camera, poses, kAll));
  const Eigen::Isometry3d held = estimator.state().object("block").table_from_object;
  const std::vector<std::string> no_block = {"table", "target", "end_effector"};
  for (int i = 1; i <= 7; ++i) {
    const TaskState& s = estimator.update(0.1 * i, perfect_detections(config, camera, poses, no_block));
    EXPECT_TRUE(s.object("block").table_from_object.isApprox(held, 1e-12));
    EXPECT_TRUE(s.object("block").stale);
    EXPECT_EQ(s.object("block").source, EstimateSource::kHeld);
    EXPECT_EQ(s.object("block").misses, i);
    EXPECT_NEAR(s.object("block").age, 0.1 * i, 1e-9);
    EXPECT_EQ(s.object("block").valid, i <= 5);  // invalid once missed more than max_misses times
    EXPECT_TRUE(s.vector().allFinite());
    EXPECT_FALSE(s.object("target").stale);
  }
  const TaskState& back = estimator.update(0.8, perfect_detections(config, camera, poses, kAll));
  EXPECT_FALSE(back.object("block").stale);
  EXPECT_TRUE(back.object("block").valid);
  EXPECT_EQ(back.object("block").misses, 0);
}

TEST(StateEstimator, WithoutTheTableFrameNothingIsValidButNothingIsNaN) {
  const TagConfig config = test::sawyer_tags();
  StateEstimator estimator(config);
  const TaskState& s = estimator.update(0.0, {});
  EXPECT_FALSE(s.table_known);
  EXPECT_FALSE(s.valid());
  EXPECT_FALSE(s.object("block").ever_measured);
  EXPECT_EQ(s.object("block").source, EstimateSource::kNone);
  EXPECT_TRUE(s.vector().allFinite());
  // Object tags without the table's tag cannot be placed in the table frame yet.
  const Eigen::Isometry3d camera = TabletopScene::default_camera_pose();
  const TaskState& t =
      estimator.update(0.1, perfect_detections(config, camera, TabletopScene::example_poses(), {"block"}));
  EXPECT_FALSE(t.object("block").valid);
  // A non-finite detection is a miss, not a NaN in the state.
  std::vector<TagDetection> bad = perfect_detections(config, camera, TabletopScene::example_poses(), kAll);
  bad[1].camera_from_tag(0, 3) = NAN;
  const TaskState& u = estimator.update(0.2, bad);
  EXPECT_TRUE(u.table_known);
  EXPECT_FALSE(u.object("block").valid);
  EXPECT_TRUE(u.object("target").valid);
  EXPECT_TRUE(u.object("block").table_from_object.matrix().allFinite());
}

TEST(StateEstimator, RejectsBadTimesAndIncompleteConfigs) {
  const TagConfig config = test::sawyer_tags();
  StateEstimator estimator(config);
  estimator.update(1.0, {});
  EXPECT_NE(error_of([&] { estimator.update(0.5, {}); }).find("time went backwards (0.5 after 1)"),
            std::string::npos);
  EXPECT_NE(error_of([&] { estimator.update(NAN, {}); }).find("time is not finite"), std::string::npos);
  const TagConfig no_target = TagConfig::parse(
      "family: tag36h11\ntags:\n  - {id: 0, name: table, size: 0.05, table_pose: [0, 0, 0, 0]}\n"
      "  - {id: 1, name: block, size: 0.03}\n  - {id: 3, name: end_effector, size: 0.03}\n",
      "t");
  EXPECT_NE(error_of([&] { StateEstimator e(no_target); }).find("no tag named 'target'"), std::string::npos);
  const TagConfig no_reference = TagConfig::parse(
      "family: tag36h11\ntags:\n  - {id: 1, name: block, size: 0.03}\n  - {id: 2, name: target, size: 0.05}\n"
      "  - {id: 3, name: end_effector, size: 0.03}\n",
      "t");
  EXPECT_NE(error_of([&] { StateEstimator e(no_reference); }).find("no reference tag"), std::string::npos);
  StateEstimator with_prior(no_reference, {}, TabletopScene::default_camera_pose());  // extrinsics suffice
  EXPECT_TRUE(with_prior.update(0.0, {}).table_known);
}

// The whole chain on rendered frames: the end-effector moves over the block and hides its tag. Without
// colour tracking the block's estimate is held and flagged stale; it never jumps or becomes NaN.
TEST(StateEstimator, OccludedTagOnRenderedFramesIsHeldAndFlaggedStale) {
  const TagConfig config = test::sawyer_tags();
  CameraModel camera;
  camera.set_world_from_camera(TabletopScene::default_camera_pose());
  const TabletopScene scene(config);
  SyntheticCamera renderer(camera);
  renderer.set_static_quads(scene.static_quads());
  PerceptionOptions o;
  o.colour_fallback = false;
  o.estimator.max_misses = 100;
  PerceptionPipeline pipeline(camera, config, o);
  TabletopPoses poses = TabletopScene::example_poses();
  const Eigen::Vector3d block = poses.block.translation();
  int stale_frames = 0;
  Eigen::Isometry3d last_fresh = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 12; ++i) {
    // Frames 4..7: the end-effector hangs between the camera and the block, hiding the block's tag.
    const bool over = i >= 4 && i <= 7;
    poses.end_effector = over ? pose_from_xyz_rpy(block.x(), block.y() - 0.065, 0.07, 0, 0, 0.0)
                              : pose_from_xyz_rpy(0.06, 0.02, 0.01, 0, 0, 0.1);
    ImageEffects e;
    e.noise_sigma = 1.5;
    e.seed = static_cast<uint64_t>(i);
    const FrameResult& r = pipeline.process(renderer.render(scene.object_quads(poses), e), 0.1 * i);
    const ObjectEstimate& b = r.state.object("block");
    ASSERT_TRUE(b.table_from_object.matrix().allFinite());
    ASSERT_TRUE(r.state.vector().allFinite());
    EXPECT_TRUE(b.valid) << i;
    EXPECT_LT((b.table_from_object.translation() - block).norm(), 0.003) << i;
    if (over) {
      ++stale_frames;
      EXPECT_TRUE(b.stale) << i;
      EXPECT_EQ(b.misses, stale_frames);
      EXPECT_TRUE(b.table_from_object.isApprox(last_fresh, 1e-12)) << i;  // held exactly, no drift
    } else {
      EXPECT_FALSE(b.stale) << i;
      last_fresh = b.table_from_object;
    }
  }
  EXPECT_EQ(stale_frames, 4);
}

// With colour tracking on, a block whose tag cannot be read is still located, from its colour.
TEST(StateEstimator, ColourFallbackLocatesABlockWithoutAReadableTag) {
  const TagConfig config = test::sawyer_tags();
  CameraModel camera;
  camera.set_world_from_camera(TabletopScene::default_camera_pose());
  // Rendered without the block's tag (a blank top face), perceived with the full config.
  const TagConfig no_block_tag = TagConfig::parse(
      "family: tag36h11\ntags:\n  - {id: 0, name: table, size: 0.048, table_pose: [0, 0, 0, 0]}\n"
      "  - {id: 2, name: target, size: 0.048, object_offset: [0, 0, -0.0015]}\n"
      "  - {id: 3, name: end_effector, size: 0.033, object_offset: [0, 0, -0.10]}\n",
      "t");
  const TabletopScene with_tag(config), without_tag(no_block_tag);
  const SyntheticCamera renderer(camera);
  PerceptionPipeline pipeline(camera, config);
  TabletopPoses poses = TabletopScene::example_poses();
  pipeline.process(renderer.render(with_tag.quads(poses)), 0.0);
  poses.block = pose_from_xyz_rpy(0.26, 0.1, 0.025, 0, 0, 0.3);  // pushed 7 cm while unreadable
  const FrameResult& r = pipeline.process(renderer.render(without_tag.quads(poses)), 0.1);
  EXPECT_EQ(r.state.object("block").source, EstimateSource::kColour);
  EXPECT_FALSE(r.state.object("block").stale);
  ASSERT_TRUE(r.colour.has_value());
  EXPECT_LT((r.state.object("block").table_from_object.translation().head<2>() -
             poses.block.translation().head<2>())
                .norm(),
            0.005);
  EXPECT_NEAR(yaw_of(r.state.object("block").table_from_object.linear()), 0.3,
              1e-3);  // orientation held from the tag
}

// A task names its own objects: here two blocks, one with a tag on top and one on a side face, and an
// end-effector; nothing is fixed to the pushing task's three.
TEST(StateEstimator, TracksTheObjectsATaskNames) {
  // The side tag sits on the object's +x face, facing along it (built in code: the YAML form has offsets
  // only).
  std::vector<TagSpec> specs(4);
  specs[0] = {0, "table", 0.05, Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()};
  specs[1] = {4, "a_top", 0.04, Eigen::Isometry3d(Eigen::Translation3d(0, 0, -0.025)), std::nullopt};
  const Eigen::Isometry3d object_from_side =
      Eigen::Translation3d(0.025, 0, 0) * Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY());
  specs[2] = {5, "a_side", 0.04, object_from_side.inverse(), std::nullopt};
  specs[3] = {6, "hand", 0.04, Eigen::Isometry3d::Identity(), std::nullopt};
  const TagConfig config("tag36h11", specs);
  StateEstimatorOptions o;
  o.objects = {{"a", {"a_top", "a_side"}, false, std::nullopt}, {"hand", {}, false, std::nullopt}};
  const Eigen::Isometry3d camera = TabletopScene::default_camera_pose();
  const Eigen::Isometry3d a = pose_from_xyz_rpy(0.3, 0.1, 0.2, 0.1, -0.05, 0.7);  // lifted and tilted
  const Eigen::Isometry3d hand = pose_from_xyz_rpy(0.3, 0.1, 0.3, 0, 0, 0.2);
  auto detection = [&](const std::string& name, const Eigen::Isometry3d& object, double margin) {
    const TagSpec& spec = config.by_name(name);
    TagDetection d;
    d.id = spec.id;
    d.name = name;
    d.camera_from_tag = camera.inverse() * (spec.table_from_tag ? *spec.table_from_tag
                                                                : object * spec.tag_from_object.inverse());
    d.decision_margin = margin;
    return d;
  };
  StateEstimator estimator(config, o);
  const TaskState& s = estimator.update(
      0.0, {detection("table", a, 80), detection("a_top", a, 60), detection("hand", hand, 70)});
  ASSERT_TRUE(s.valid());
  EXPECT_EQ(s.names, (std::vector<std::string>{"a", "hand"}));
  EXPECT_TRUE(s.object("a").table_from_object.isApprox(a, 1e-9));  // 3-D: height and tilt kept
  EXPECT_TRUE(s.object("hand").table_from_object.isApprox(hand, 1e-9));
  EXPECT_EQ(s.vector().size(), 0);  // not the pushing task
  EXPECT_NE(error_of([&] { s.object("block"); }).find("no tracked object 'block'; tracked: a, hand"),
            std::string::npos);
  // Only the side tag seen (the top hidden, e.g. under a gripper): the object is still measured, whole.
  StateEstimator other(config, o);
  const TaskState& t =
      other.update(0.0, {detection("table", a, 80), detection("a_side", a, 50), detection("hand", hand, 70)});
  EXPECT_EQ(t.object("a").source, EstimateSource::kTag);
  EXPECT_TRUE(t.object("a").table_from_object.isApprox(a, 1e-9));
  // An unknown tag name, a duplicate object and the reference tag as an object are refused.
  StateEstimatorOptions bad = o;
  bad.objects[0].tags = {"a_top", "nope"};
  EXPECT_NE(error_of([&] { StateEstimator e(config, bad); }).find("no tag named 'nope'"), std::string::npos);
  bad.objects = {{"hand", {}, false, std::nullopt}, {"hand", {}, false, std::nullopt}};
  EXPECT_NE(error_of([&] { StateEstimator e(config, bad); }).find("listed twice"), std::string::npos);
  bad.objects = {{"t", {"table"}, false, std::nullopt}};
  EXPECT_NE(error_of([&] { StateEstimator e(config, bad); }).find("names the reference tag"),
            std::string::npos);
}

// Two tags of one object seen together: positions averaged, orientation from the larger decision margin.
TEST(StateEstimator, FusesSeveralTagsOfOneObject) {
  const TagConfig config = TagConfig::parse(
      "family: tag36h11\ntags:\n  - {id: 0, name: table, size: 0.05, table_pose: [0, 0, 0, 0]}\n"
      "  - {id: 4, name: a_top, size: 0.04}\n  - {id: 5, name: a_side, size: 0.04}\n",
      "t");
  StateEstimatorOptions o;
  o.objects = {{"a", {"a_top", "a_side"}, false, std::nullopt}};
  StateEstimator estimator(config, o);
  const Eigen::Isometry3d camera = TabletopScene::default_camera_pose();
  auto detection = [&](int id, const Eigen::Isometry3d& table_from_tag, double margin) {
    TagDetection d;
    d.id = id;
    d.camera_from_tag = camera.inverse() * table_from_tag;
    d.decision_margin = margin;
    return d;
  };
  const Eigen::Isometry3d p1 = pose_from_xyz_rpy(0.3, 0.1, 0.1, 0, 0, 0.2);
  const Eigen::Isometry3d p2 =
      pose_from_xyz_rpy(0.302, 0.1, 0.1, 0, 0, 0.25);  // a slightly different reading
  const TaskState& s = estimator.update(
      0.0, {detection(0, Eigen::Isometry3d::Identity(), 90), detection(4, p1, 40), detection(5, p2, 60)});
  const Eigen::Isometry3d& e = s.object("a").table_from_object;
  EXPECT_NEAR(e.translation().x(), 0.301, 1e-9);
  EXPECT_NEAR(yaw_of(e.linear()), 0.25, 1e-9);
}

// An object resting on the table: its height is the known one and only its yaw is kept.
TEST(StateEstimator, PlanarObjectsKeepTheirHeightAndYawOnly) {
  const TagConfig config = test::sawyer_tags();
  StateEstimatorOptions o;
  o.objects = pushing_objects();
  o.objects[0].planar_height = 0.025;
  StateEstimator estimator(config, o);
  const Eigen::Isometry3d camera = TabletopScene::default_camera_pose();
  TabletopPoses poses = TabletopScene::example_poses();
  poses.block = pose_from_xyz_rpy(0.2, 0.05, 0.031, 0.05, -0.04, 0.3);  // a noisy reading: off height, tilted
  const TaskState& s = estimator.update(0.0, perfect_detections(config, camera, poses, kAll));
  const Eigen::Isometry3d& b = s.object("block").table_from_object;
  EXPECT_DOUBLE_EQ(b.translation().z(), 0.025);
  EXPECT_NEAR(b.translation().x(), 0.2, 1e-9);
  EXPECT_NEAR(yaw_of(b.linear()), yaw_of(poses.block.linear()), 1e-9);
  EXPECT_NEAR(b.linear()(2, 2), 1.0, 1e-12);  // upright
  // Objects without a planar height are left as measured.
  EXPECT_TRUE(s.object("end_effector").table_from_object.isApprox(poses.end_effector, 1e-9));
}

// save() and restore() carry the whole filter: a restored estimator continues bit for bit as the original.
TEST(StateEstimator, SnapshotsRestoreTheFilterExactly) {
  const TagConfig config = test::sawyer_tags();
  const Eigen::Isometry3d camera = TabletopScene::default_camera_pose();
  StateEstimator a(config);
  TabletopPoses poses = TabletopScene::example_poses();
  auto frame = [&](int i, bool hide_block) {
    poses.block = pose_from_xyz_rpy(0.2 + 0.003 * i, 0.05, 0.025, 0, 0, 0.3 + 0.01 * i);
    return perfect_detections(
        config, camera, poses,
        hide_block ? std::vector<std::string>{"table", "target", "end_effector"} : kAll);
  };
  for (int i = 0; i < 4; ++i)
    a.update(0.1 * i, frame(i, i == 3));
  const std::vector<double> saved = a.save();
  std::vector<TaskState> original;
  for (int i = 4; i < 8; ++i)
    original.push_back(a.update(0.1 * i, frame(i, i == 5)));
  StateEstimator b(config);
  b.update(0.0, frame(0, false));  // some other history, overwritten by restore
  b.restore(saved);
  for (int i = 4; i < 8; ++i) {
    const TaskState& s = b.update(0.1 * i, frame(i, i == 5));
    const TaskState& r = original[static_cast<size_t>(i - 4)];
    EXPECT_EQ(s.frame, r.frame);
    for (size_t k = 0; k < s.objects.size(); ++k) {
      EXPECT_EQ(s.objects[k].table_from_object.matrix(), r.objects[k].table_from_object.matrix()) << i;
      EXPECT_EQ(s.objects[k].misses, r.objects[k].misses);
      EXPECT_EQ(s.objects[k].source, r.objects[k].source);
      EXPECT_EQ(s.objects[k].age, r.objects[k].age);
    }
    EXPECT_EQ(s.vector(), r.vector());
  }
  std::vector<double> bad = saved;
  bad.pop_back();
  EXPECT_NE(error_of([&] { b.restore(bad); }).find("expected"), std::string::npos);
  bad = saved;
  bad[3] = NAN;
  EXPECT_NE(error_of([&] { b.restore(bad); }).find("NaN or Inf"), std::string::npos);
}

}  // namespace
}  // namespace hlt
