// The robot arms and tabletop scene (envs/robot/): the Jacobian against finite differences of the forward
// kinematics, commanded against achieved tool velocity, joint limits and speed limits, the workspace clamp,
// the low-pass filter, the wrist wrench against a held block's weight, exact snapshots with contacts, render.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include <btBulletDynamicsCommon.h>

#include <BulletDynamics/Featherstone/btMultiBodyDynamicsWorld.h>

#include "envs/robot/arm.h"
#include "envs/robot/ee_control.h"
#include "envs/robot/tabletop.h"
#include "hlt/util/error.h"

namespace hlt::robot {
namespace {

constexpr double kG = 9.8;

// Tool pointing down, its x axis along the world's x.
Eigen::Isometry3d tool_down(const Eigen::Vector3d& p) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::Vector3d(1, -1, -1).asDiagonal();
  t.translation() = p;
  return t;
}

TabletopSettings settings_for(ArmKind kind, std::vector<BlockSpec> blocks = {BlockSpec{}}) {
  TabletopSettings s;
  s.arm = kind;
  s.blocks = std::move(blocks);
  return s;
}

// The arm at rest with the tool pointing down at `p`.
Vector7d place_tool(Tabletop& scene, const Eigen::Vector3d& p) {
  Vector7d q;
  EXPECT_TRUE(scene.arm().solve_ik(tool_down(p), scene.arm().model().seed, &q)) << scene.arm().model().name;
  scene.reset_arm(q, scene.arm().model().finger_travel);
  return q;
}

class Arms : public testing::TestWithParam<ArmKind> {};

std::string arm_name(const testing::TestParamInfo<ArmKind>& info) {
  return info.param == ArmKind::kSawyer ? "Sawyer" : "Panda";
}

TEST_P(Arms, ModelHasSevenLimitedJointsAndAHand) {
  Tabletop scene(settings_for(GetParam()));
  const ArmModel& m = scene.arm().model();
  for (int k = 0; k < 7; ++k) {
    EXPECT_LT(m.lower[k], m.upper[k]);
    EXPECT_GT(m.max_speed[k], 0);
    const auto& link = m.spec.links[m.joints[k]];
    EXPECT_EQ(link.joint, bullet::JointType::kRevolute);
    ASSERT_TRUE(link.limits.has_value());
    EXPECT_EQ(link.limits->first, m.lower[k]);
  }
  EXPECT_EQ(m.spec.links[m.hand].joint, bullet::JointType::kFixed);
  EXPECT_EQ(m.fingers.size(), GetParam() == ArmKind::kPanda ? 2u : 0u);
}

TEST_P(Arms, JacobianMatchesFiniteDifferencesOfForwardKinematics) {
  Tabletop scene(settings_for(GetParam()));
  Arm& arm = scene.arm();
  const ArmModel& m = arm.model();
  std::mt19937_64 rng(4);
  double worst_linear = 0, worst_angular = 0;
  for (int trial = 0; trial < 6; ++trial) {
    Vector7d q = m.seed;
    if (trial > 0) {
      for (int k = 0; k < 7; ++k) {
        std::uniform_real_distribution<double> u(m.lower[k] + 0.1, m.upper[k] - 0.1);
        q[k] = u(rng);
      }
    }
    arm.set_configuration(q);
    const Jacobian j = arm.jacobian();
    const double eps = 1e-6;
    for (int k = 0; k < 7; ++k) {
      Vector7d qp = q, qm = q;
      qp[k] += eps;
      qm[k] -= eps;
      arm.set_configuration(qp);
      const Eigen::Isometry3d tp = arm.tool_pose();
      arm.set_configuration(qm);
      const Eigen::Isometry3d tm = arm.tool_pose();
      const Eigen::Vector3d dp = (tp.translation() - tm.translation()) / (2 * eps);
      const Eigen::Vector3d dw = orientation_error(tp.linear(), tm.linear()) / (2 * eps);
      worst_linear = std::max(worst_linear, (dp - j.col(k).head<3>()).cwiseAbs().maxCoeff());
      worst_angular = std::max(worst_angular, (dw - j.col(k).tail<3>()).cwiseAbs().maxCoeff());
    }
    // Not a degenerate Jacobian: the tool moves with the joints.
    EXPECT_GT(j.norm(), 0.5);
  }
  std::printf(
      "[%s] Jacobian vs central differences (6 configurations): max |error| linear %.2e m/rad, "
      "angular %.2e rad/rad\n",
      m.name.c_str(), worst_linear, worst_angular);
  EXPECT_LT(worst_linear, 1e-7);
  EXPECT_LT(worst_angular, 1e-7);
}

TEST_P(Arms, AchievedToolVelocityFollowsTheCommand) {
  TabletopSettings s = settings_for(GetParam(), {});
  Tabletop scene(s);
  place_tool(scene, {0.55, -0.05, 0.2});
  const Eigen::Vector3d v(0.06, 0.04, -0.02);
  Vector6d twist = Vector6d::Zero();
  twist.head<3>() = v;
  // The first step takes the arm from rest; from then on the tool should move at the commanded velocity.
  scene.step(twist);
  const Eigen::Isometry3d start = scene.arm().tool_pose();
  const int steps = 10;
  double worst_instant = 0;
  for (int i = 0; i < steps; ++i) {
    scene.step(twist);
    worst_instant = std::max(worst_instant, (scene.arm().tool_twist().head<3>() - v).norm());
  }
  const Eigen::Isometry3d end = scene.arm().tool_pose();
  const Eigen::Vector3d mean_v = (end.translation() - start.translation()) / (steps * s.control_dt);
  const double drift = orientation_error(end.linear(), start.linear()).norm();
  std::printf(
      "[%s] commanded |v| %.4f m/s over 1 s: mean velocity error %.2e m/s (%.2f%%), worst "
      "end-of-step error %.2e m/s, orientation drift %.2e rad\n",
      scene.arm().model().name.c_str(), v.norm(), (mean_v - v).norm(), 100 * (mean_v - v).norm() / v.norm(),
      worst_instant, drift);
  EXPECT_LT((mean_v - v).norm(), 0.02 * v.norm());
  EXPECT_LT(worst_instant, 0.05 * v.norm());
  EXPECT_LT(drift, 0.01);
}

TEST_P(Arms, JointsStayWithinPositionAndSpeedLimits) {
  Tabletop scene(settings_for(GetParam(), {}));
  place_tool(scene, {0.5, 0.0, 0.3});
  const ArmModel& m = scene.arm().model();
  // Far out of reach and turning: the arm stretches until joints reach their limits or it is straight.
  Vector6d twist;
  twist << 0.5, 0.3, 0.4, 0.0, 0.0, 2.0;
  double worst_over = -1, worst_speed_ratio = 0;
  for (int i = 0; i < 60; ++i) {
    scene.step(twist);
    const Vector7d q = scene.arm().positions(), qd = scene.arm().velocities();
    for (int k = 0; k < 7; ++k) {
      worst_over = std::max({worst_over, q[k] - m.upper[k], m.lower[k] - q[k]});
      worst_speed_ratio = std::max(worst_speed_ratio, std::abs(qd[k]) / m.max_speed[k]);
    }
  }
  // Some joint got near a limit, and none crossed it.
  std::printf(
      "[%s] 6 s of an unreachable command: closest approach to a joint limit %.4f rad (negative: "
      "inside), fastest joint %.3f of its limit\n",
      m.name.c_str(), worst_over, worst_speed_ratio);
  EXPECT_LT(worst_over, 1e-3);
  EXPECT_GT(worst_over, -0.2);
  EXPECT_LT(worst_speed_ratio, 1.01);
}

TEST_P(Arms, WorkspaceClampKeepsTheToolInside) {
  TabletopSettings s = settings_for(GetParam(), {});
  s.control.workspace =
      Eigen::AlignedBox3d(Eigen::Vector3d(0.5, -0.2, 0.1), Eigen::Vector3d(0.75, 0.25, 0.4));
  Tabletop scene(s);
  place_tool(scene, {0.6, 0.0, 0.2});
  Vector6d twist = Vector6d::Zero();
  twist.head<3>() << 0.2, -0.15, -0.1;
  for (int i = 0; i < 30; ++i)
    scene.step(twist);
  const Eigen::Vector3d p = scene.arm().tool_pose().translation();
  // At the corner the command drives into, within 5 mm.
  EXPECT_NEAR(p.x(), 0.75, 0.005);
  EXPECT_NEAR(p.y(), -0.2, 0.005);
  EXPECT_NEAR(p.z(), 0.1, 0.005);
}

TEST_P(Arms, HeldHeightAndOrientationOverrideTheCommand) {
  TabletopSettings s = settings_for(GetParam(), {});
  s.control.hold_height = 0.2;
  s.control.hold_orientation = tool_down({0, 0, 0}).linear();
  Tabletop scene(s);
  // Start 2 cm off the held height: the hold brings the tool back.
  place_tool(scene, {0.55, -0.05, 0.22});
  // The command asks to climb and to turn; both are replaced by the holds, the planar part is followed.
  Vector6d twist;
  twist << 0.05, 0.03, 0.1, 0.3, -0.2, 0.5;
  for (int i = 0; i < 20; ++i)
    scene.step(twist);
  const Eigen::Isometry3d end = scene.arm().tool_pose();
  const double tilt = orientation_error(*s.control.hold_orientation, end.linear()).norm();
  std::printf(
      "[%s] 2 s of a climbing, turning command under the holds: height error %.2e m, orientation %.2e rad\n",
      scene.arm().model().name.c_str(), end.translation().z() - 0.2, tilt);
  EXPECT_NEAR(end.translation().z(), 0.2, 1e-3);
  EXPECT_LT(tilt, 2e-3);
  EXPECT_NEAR(end.translation().x(), 0.55 + 0.05 * 2.0, 0.01);
  EXPECT_NEAR(end.translation().y(), -0.05 + 0.03 * 2.0, 0.01);
}

TEST(EeControl, LowPassFilterAndHelpers) {
  EeControlSettings s;
  s.filter = 0.75;
  EeVelocityController c(s);
  Vector6d v = Vector6d::Zero();
  v[0] = 1.0;
  c.command(v);
  EXPECT_DOUBLE_EQ(c.filtered()[0], 0.25);
  c.command(v);
  EXPECT_DOUBLE_EQ(c.filtered()[0], 0.25 * 0.75 + 0.25);
  EeControlSettings unstable;
  unstable.filter = 1.0;  // would never follow the command
  EXPECT_THROW(EeVelocityController{unstable}, Error);

  Vector7d qd;
  qd << 1, -4, 0, 0, 0, 0, 2;
  const Vector7d limited = limit_speeds(qd, Vector7d::Constant(2.0));
  EXPECT_DOUBLE_EQ(limited[1], -2.0);
  EXPECT_DOUBLE_EQ(limited[0], 0.5);

  const Eigen::AlignedBox3d box(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones());
  const Eigen::Vector3d clamped = clamp_to_workspace({0.95, 0.5, 0.02}, {1.0, 1.0, -1.0}, box, 0.1);
  EXPECT_NEAR(clamped.x(), 0.5, 1e-12);
  EXPECT_DOUBLE_EQ(clamped.y(), 1.0);
  EXPECT_NEAR(clamped.z(), -0.2, 1e-12);
  // Back towards the inside is always allowed.
  EXPECT_DOUBLE_EQ(clamp_to_workspace({1.5, 0.5, 0.5}, {-1.0, 0, 0}, box, 0.1).x(), -1.0);

  // Damped least squares solves a well-conditioned Jacobian almost exactly.
  Jacobian j = Jacobian::Zero();
  for (int k = 0; k < 6; ++k)
    j(k, k) = 1.0 + k;
  Vector6d t;
  t << 1, 2, 3, 4, 5, 6;
  const Vector7d sol = damped_least_squares(j, t, 1e-4);
  EXPECT_LT((j * sol - t).norm(), 1e-6);
}

INSTANTIATE_TEST_SUITE_P(Robot, Arms, testing::Values(ArmKind::kSawyer, ArmKind::kPanda), arm_name);

// A 0.5 kg 5 cm block at (0.5, 0) on the Panda's table.
constexpr double kHeldMass = 0.5;
std::unique_ptr<Tabletop> panda_with_block() {
  BlockSpec block;
  block.mass = kHeldMass;
  block.half_extents = Eigen::Vector3d(0.025, 0.025, 0.025);
  auto scene = std::make_unique<Tabletop>(settings_for(ArmKind::kPanda, {block}));
  scene->set_block(0, {0.5, 0.0, 0.025}, 0.0);
  return scene;
}

// From the open fingers around the block: close on it for 1 s, then lift it at 0.1 m/s for 1 s.
void grasp_and_lift(Tabletop& scene) {
  for (int i = 0; i < 10; ++i)
    scene.step(Vector6d::Zero(), -0.1);
  Vector6d up = Vector6d::Zero();
  up[2] = 0.1;
  for (int i = 0; i < 10; ++i)
    scene.step(up, -0.1);
}

TEST(Tabletop, WristForceMeasuresTheWeightOfAHeldBlock) {
  auto owned = panda_with_block();
  Tabletop& scene = *owned;
  place_tool(scene, {0.5, 0.0, 0.03});
  Vector6d still = Vector6d::Zero();
  // Open, at rest around the block: the wrist carries the hand and fingers only.
  for (int i = 0; i < 5; ++i)
    scene.step(still, 0.0);
  const Vector6d empty = scene.wrist_wrench();
  // Close on the block, lift it 10 cm, hold it still.
  grasp_and_lift(scene);
  // Held still: the stop's deceleration is over after a few steps.
  for (int i = 0; i < 5; ++i)
    scene.step(still, -0.1);
  Vector6d sum = Vector6d::Zero();
  for (int i = 0; i < 10; ++i) {
    scene.step(still, -0.1);
    sum += scene.wrist_wrench();
  }
  const Vector6d held = sum / 10;
  const double lifted = scene.block_pose(0).translation().z();
  const double hand_weight = (0.73 + 2 * 0.015) * kG;
  std::printf(
      "[panda] wrist force at rest open %.4f N (hand and fingers weigh %.4f N); holding the %.2f kg "
      "block lifted to z %.3f m: %.4f N, change %.4f N against its weight %.4f N\n",
      empty[2], -hand_weight, kHeldMass, lifted, held[2], held[2] - empty[2], -kHeldMass * kG);
  EXPECT_GT(lifted, 0.1);
  EXPECT_NEAR(empty[2], -hand_weight, 0.02 * hand_weight);
  EXPECT_NEAR(held[2] - empty[2], -kHeldMass * kG, 0.02 * kHeldMass * kG);
  // Held still, the force is vertical.
  EXPECT_LT(held.head<2>().norm(), 0.05 * kHeldMass * kG);
}

TEST(Tabletop, ExternalForceLeavesOutTheHandsOwnWeightAndAcceleration) {
  auto owned = panda_with_block();
  Tabletop& scene = *owned;
  place_tool(scene, {0.5, -0.2, 0.15});
  const double hand_weight = (0.73 + 2 * 0.015) * kG;
  // Reset: nothing measured yet, the wrist reads its resting value.
  EXPECT_NEAR(scene.wrist_wrench()[2], -hand_weight, 1e-9);
  EXPECT_LT(scene.external_force().norm(), 1e-12);
  // In free air, speeding up and stopping along y and z: the wrist force swings by m a (0.76 kg, up to
  // ~1.5 m/s^2), the external force stays near zero.
  Vector6d v = Vector6d::Zero();
  double raw_swing = 0, external_worst = 0;
  for (int i = 0; i < 12; ++i) {
    v[1] = (i % 4 < 2) ? 0.15 : -0.15;
    v[2] = (i % 3 == 0) ? 0.1 : 0.0;
    scene.step(v, 0.04);
    const Eigen::Vector3d raw = scene.wrist_wrench().head<3>() - Eigen::Vector3d(0, 0, -hand_weight);
    raw_swing = std::max(raw_swing, raw.norm());
    external_worst = std::max(external_worst, scene.external_force().norm());
  }
  std::printf(
      "[panda] free hand under changing velocity commands: wrist force less weight up to %.3f N, "
      "external force up to %.3f N\n",
      raw_swing, external_worst);
  EXPECT_GT(raw_swing, 0.5);
  EXPECT_LT(external_worst, 0.1 * raw_swing);
  // Snapshots carry it.
  const std::vector<double> snap = scene.save_state();
  const Eigen::Vector3d before = scene.external_force();
  scene.step(v, 0.04);
  scene.restore_state(snap);
  EXPECT_EQ(scene.external_force(), before);
  // Holding a block still, it is the block's weight.
  place_tool(scene, {0.5, 0.0, 0.03});
  grasp_and_lift(scene);
  for (int i = 0; i < 5; ++i)
    scene.step(Vector6d::Zero(), -0.1);
  EXPECT_GT(scene.block_pose(0).translation().z(), 0.1);
  EXPECT_NEAR(scene.external_force()[2], -kHeldMass * kG, 0.03 * kHeldMass * kG);
  EXPECT_LT(scene.external_force().head<2>().norm(), 0.05 * kHeldMass * kG);
}

TEST(Tabletop, ASlidingBlockStopsWhereCoulombFrictionSays) {
  BlockSpec block;
  block.friction = 0.5;
  TabletopSettings s = settings_for(ArmKind::kSawyer, {block});
  s.table_friction = 0.6;
  Tabletop scene(s);
  place_tool(scene, {0.5, -0.3, 0.3});
  scene.set_block(0, {0.5, 0.3, 0.025}, 0.0);
  // Bullet combines the two frictions as their product; sliding decelerates at mu g.
  const double mu = 0.5 * 0.6, v0 = 0.5;
  bullet::Robot& b = *scene.world().robots().back();
  b.set_base_state(b.base_position(), b.base_orientation(), Eigen::Vector3d(v0, 0, 0),
                   Eigen::Vector3d::Zero());
  for (int i = 0; i < 5; ++i)
    scene.step(Vector6d::Zero());
  const Eigen::Vector3d p = scene.block_pose(0).translation();
  // v^2 / (2 mu g), less the v0 h / 2 that semi-implicit Euler's velocity-first update takes off (h = 1/240
  // s).
  const double h = s.control_dt / s.substeps;
  const double expected = v0 * v0 / (2 * mu * kG) - 0.5 * v0 * h;
  std::printf(
      "[tabletop] block sliding from %.2f m/s on friction %.2f: stopped after %.5f m (Coulomb, time-stepped: "
      "%.5f m), "
      "speed %.1e m/s, height %.5f m\n",
      v0, mu, p.x() - 0.5, expected, scene.block_velocity(0).norm(), p.z());
  EXPECT_NEAR(p.x() - 0.5, expected, 0.02 * expected);
  EXPECT_NEAR(p.y(), 0.3, 1e-3);
  EXPECT_NEAR(p.z(), 0.025, 1e-3);
  EXPECT_LT(scene.block_velocity(0).norm(), 1e-3);
}

TEST(Tabletop, ContactPairsLastWithBoxSizedThresholds) {
  Tabletop scene(settings_for(ArmKind::kPanda, {BlockSpec{}, BlockSpec{}}));
  btDispatcher& d = *scene.world().bullet().getDispatcher();
  const int n = d.getNumManifolds();
  // Fingers and hand with each block and the table, the blocks with each other and the table.
  EXPECT_EQ(n, 3 * 3 + 1 + 2);
  double worst = 0;
  for (int i = 0; i < n; ++i)
    worst = std::max(worst, double(d.getManifoldByIndexInternal(i)->getContactBreakingThreshold()));
  // Bullet's 0.02 x the smaller body's bounding-sphere radius (world-sized bounds gave 3.5 m).
  EXPECT_LT(worst, 0.02);
  place_tool(scene, {0.5, 0.0, 0.2});
  scene.set_block(0, {1.0, 0.6, 0.025}, 0.0);
  scene.set_block(1, {0.6, -0.5, 0.4}, 0.5);  // falls onto the table, far from everything else
  for (int i = 0; i < 10; ++i)
    scene.step(Vector6d::Zero());
  EXPECT_NEAR(scene.block_pose(1).translation().z(), 0.025, 1e-3);
  EXPECT_EQ(d.getNumManifolds(), n);
}

// Pushes the block with the tool (the Sawyer) or grasps it (the Panda): contacts throughout.
void contact_steps(Tabletop& scene, int steps, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < steps; ++i) {
    Vector6d twist = Vector6d::Zero();
    twist[0] = 0.08 + 0.05 * u(rng);
    twist[1] = 0.05 * u(rng);
    scene.step(twist, 0.1 * u(rng));
  }
}

TEST(Tabletop, SnapshotsReproduceContactsExactly) {
  for (ArmKind kind : {ArmKind::kSawyer, ArmKind::kPanda}) {
    const TabletopSettings s = settings_for(kind, {BlockSpec{}, BlockSpec{}});
    Tabletop scene(s);
    scene.set_block(0, {0.6, 0.0, 0.025}, 0.3);
    scene.set_block(1, {0.7, 0.1, 0.025}, -0.2);
    place_tool(scene, {0.5, 0.0, 0.025});
    contact_steps(scene, 8, 1);
    const std::vector<double> snap = scene.save_state();
    contact_steps(scene, 20, 2);
    const std::vector<double> after = scene.save_state();
    // The tool reached the first block and moved it.
    EXPECT_GT((scene.block_pose(0).translation() - Eigen::Vector3d(0.6, 0.0, 0.025)).norm(), 0.01);
    scene.restore_state(snap);
    contact_steps(scene, 20, 2);
    EXPECT_EQ(scene.save_state(), after);
    Tabletop fresh(s);
    fresh.restore_state(snap);
    contact_steps(fresh, 20, 2);
    EXPECT_EQ(fresh.save_state(), after);
    std::vector<double> bad = snap;
    bad.pop_back();
    EXPECT_THROW(fresh.restore_state(bad), Error);
  }
}

TEST(Tabletop, RendersBothViews) {
  for (ArmKind kind : {ArmKind::kSawyer, ArmKind::kPanda}) {
    Tabletop scene(settings_for(kind));
    scene.set_block(0, {0.6, 0.0, 0.025}, 0.3);
    place_tool(scene, {0.5, 0.0, 0.1});
    const cv::Mat img = scene.render(640, 240, {Eigen::Vector3d(0.7, 0.1, 0)});
    ASSERT_EQ(img.cols, 640);
    ASSERT_EQ(img.rows, 240);
    // The block's red shows in both halves.
    for (int half = 0; half < 2; ++half) {
      const cv::Mat part = img(cv::Rect(half * 320, 0, 320, 240));
      int red = 0;
      for (int y = 0; y < part.rows; ++y)
        for (int x = 0; x < part.cols; ++x) {
          const cv::Vec3b p = part.at<cv::Vec3b>(y, x);
          red += p[2] > 150 && p[0] < 80 && p[1] < 80;
        }
      EXPECT_GT(red, 20) << half;
    }
  }
}

}  // namespace
}  // namespace hlt::robot
