// The block-pushing task (envs/robot/block_push.h): reward and success against hand-computed values, the
// observation's layout, the reset distribution, the planar tool, and a scripted push that solves an episode.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "envs/registry.h"
#include "envs/robot/block_push.h"
#include "hlt/util/error.h"

namespace hlt::robot {
namespace {

TEST(BlockPush, RewardMatchesHandComputedValues) {
  Eigen::VectorXd o(6);
  o << 0.03, -0.04, 0.1, 0.06, 0.08, -0.2;
  // -5 * 0.1 - 10 * 0.05 - 0.01 * (0.25 + 1) = -1.0125
  EXPECT_NEAR(BlockPush::reward(o, Eigen::Vector2d(0.5, -1.0)), -1.0125, 1e-12);
  // Yaw differences do not enter the reward.
  o[2] = 2.0;
  o[5] = -3.0;
  EXPECT_NEAR(BlockPush::reward(o, Eigen::Vector2d(0.5, -1.0)), -1.0125, 1e-12);
  EXPECT_NEAR(BlockPush::reward(Eigen::VectorXd::Zero(6), Eigen::Vector2d::Zero()), 0.0, 1e-15);
  // Nor does what the robot knows of itself (the tool's position and command).
  Eigen::VectorXd full = Eigen::VectorXd::Constant(BlockPush::kObservationDim, 0.3);
  full.head<6>() = o;
  EXPECT_NEAR(BlockPush::reward(full, Eigen::Vector2d(0.5, -1.0)), -1.0125, 1e-12);
}

TEST(BlockPush, StepRewardIsThePapersFromThePoses) {
  BlockPush env;
  env.reset(0);
  env.place({0.65, 0.05, 0.3}, {0.7, -0.1, -0.5});
  // An action beyond [-1, 1] is clipped before it moves the tool or costs reward.
  const StepResult r = env.step(Eigen::Vector2d(3.0, -0.5));
  const Eigen::Vector3d e = env.scene().arm().tool_pose().translation();
  const Eigen::Vector3d b = env.scene().block_pose(0).translation();
  const Eigen::Vector2d t = env.target().head<2>();
  const double expected =
      -5.0 * (t - b.head<2>()).norm() - 10.0 * (b - e).head<2>().norm() - 0.01 * (1.0 + 0.25);
  EXPECT_NEAR(r.reward, expected, 1e-12);
  EXPECT_NEAR(r.observation[0], b.x() - e.x(), 1e-12);
  EXPECT_NEAR(r.observation[4], t.y() - b.y(), 1e-12);
  // The block did not move (the tool is 10 cm away): block -> target yaw is -0.5 - 0.3.
  EXPECT_NEAR(r.observation[5], -0.8, 1e-6);
  // The tool points down with its x along the world's, so ee -> block yaw is the block's.
  EXPECT_NEAR(r.observation[2], 0.3, 1e-3);
  ASSERT_EQ(r.observation.size(), BlockPush::kObservationDim);
  // The tool's position from the workspace's centre, and the filtered command (from rest: the share
  // 1 - kFilter of the clipped action's velocity).
  EXPECT_NEAR(r.observation[6], e.x() - 0.5 * (BlockPush::kXMin + BlockPush::kXMax), 1e-12);
  EXPECT_NEAR(r.observation[7], e.y() - 0.5 * (BlockPush::kYMin + BlockPush::kYMax), 1e-12);
  EXPECT_NEAR(r.observation[8], (1 - BlockPush::kFilter) * BlockPush::kSpeed * 1.0, 1e-12);
  EXPECT_NEAR(r.observation[9], (1 - BlockPush::kFilter) * BlockPush::kSpeed * -0.5, 1e-12);
  EXPECT_FALSE(r.done());
}

// Why the observation carries the tool's position and command: with the paper's six components alone, two
// steps from the same observation with the same action move the tool differently (here: against the
// workspace's near edge, where the clamp stops it, and in the open; and with two command histories). With
// the last four, the observations before the step differ, so a model can tell the cases apart.
TEST(BlockPush, ToolPositionAndCommandDecideTheToolsNextMove) {
  BlockPush env;
  env.reset(0);
  // At the start the tool sits on the workspace's near edge (x = kXMin): a step towards -x cannot move it.
  env.place({0.62, 0.0, 0.0}, {0.7, 0.15, 0.0});
  const Eigen::VectorXd at_edge = env.observation();
  const StepResult stopped = env.step(Eigen::Vector2d(-1.0, 0.0));
  EXPECT_NEAR(stopped.observation[6] - at_edge[6], 0.0, 1e-3);
  // The same layout of tool, block and target 5 cm further in: the same step now moves the tool.
  BlockPush open;
  open.reset(0);
  open.place({0.67, 0.0, 0.0}, {0.75, 0.15, 0.0});
  for (int i = 0; i < 30; ++i)  // bring the tool 5 cm in along +x and let the command die down
    open.step(Eigen::Vector2d(i < 3 ? 0.5 : 0.0, 0.0));
  const Eigen::VectorXd inside = open.observation();
  const StepResult moved = open.step(Eigen::Vector2d(-1.0, 0.0));
  EXPECT_LT(moved.observation[6] - inside[6], -0.01);
  // The paper's six components did not tell the two starts apart (the tool 4-5 cm in front of the block,
  // the same offsets to the target); the tool's position does.
  EXPECT_LT((inside.head<6>() - at_edge.head<6>()).cwiseAbs().maxCoeff(), 0.01);
  EXPECT_GT(inside[6] - at_edge[6], 0.04);
}

TEST(BlockPush, SuccessIsTheBlockWithinThreeCentimetresOfTheTarget) {
  BlockPush env;
  env.reset(0);
  env.place({0.6, 0.0, 0.0}, {0.62, 0.01, 1.0});  // 2.24 cm away, any yaw
  EXPECT_TRUE(env.success());
  env.place({0.6, 0.0, 0.0}, {0.63, 0.0, 0.0});  // 3 cm: not within
  EXPECT_FALSE(env.success());
  env.place({0.6, 0.0, 0.0}, {0.6, -0.0299, 0.0});
  EXPECT_TRUE(env.success());
}

TEST(BlockPush, ResetPlacesBlockAndTargetInTheWorkspace) {
  BlockPush env;
  double closest = 1e9;
  for (uint64_t seed = 0; seed < 50; ++seed) {
    const Eigen::VectorXd o = env.reset(seed);
    const Eigen::Vector3d b = env.scene().block_pose(0).translation();
    const Eigen::Vector3d t = env.target();
    for (const Eigen::Vector2d& p : {Eigen::Vector2d(b.head<2>()), Eigen::Vector2d(t.head<2>())}) {
      EXPECT_GE(p.x(), BlockPush::kXMin);
      EXPECT_LE(p.x(), BlockPush::kXMax);
      EXPECT_GE(p.y(), BlockPush::kYMin);
      EXPECT_LE(p.y(), BlockPush::kYMax);
    }
    EXPECT_NEAR(b.z(), 0.025, 1e-12);
    EXPECT_GE((t.head<2>() - b.head<2>()).norm(), 0.1);
    EXPECT_FALSE(env.success());
    closest = std::min(closest, o.head<2>().norm());
    const Eigen::Vector3d tool = env.scene().arm().tool_pose().translation();
    EXPECT_NEAR(tool.x(), BlockPush::kXMin, 1e-4);
    EXPECT_NEAR(tool.z(), BlockPush::kToolHeight, 1e-4);
  }
  EXPECT_GE(closest, 0.07 - 1e-4);
}

TEST(BlockPush, DeclaredScaleMapsResetObservationsToUnitSizedInputs) {
  BlockPush env;
  const std::optional<ObservationScale> scale = env.observation_scale();
  ASSERT_TRUE(scale.has_value());
  const int n = BlockPush::kObservationDim;
  ASSERT_EQ(scale->scale.size(), n);
  ASSERT_EQ(scale->offset.size(), n);
  Eigen::VectorXd low = Eigen::VectorXd::Constant(n, 1e9), high = -low;
  // Components [from, n) of an observation.
  auto extend = [&](const Eigen::VectorXd& o, int from) {
    const Eigen::VectorXd z = ((o - scale->offset).array() / scale->scale.array()).matrix();
    low.tail(n - from) = low.tail(n - from).cwiseMin(z.tail(n - from));
    high.tail(n - from) = high.tail(n - from).cwiseMax(z.tail(n - from));
  };
  for (uint64_t seed = 0; seed < 200; ++seed)
    extend(env.reset(seed), 0);
  // The tool starts at the same spot at rest: its position and command spread once it moves (random
  // actions, held for 5 steps each, over 10 episodes; the poses' ranges are the resets').
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (uint64_t seed = 0; seed < 10; ++seed) {
    env.reset(seed);
    Eigen::Vector2d a;
    for (int t = 0; t < BlockPush::kSteps; ++t) {
      if (t % 5 == 0) a << u(rng), u(rng);
      extend(env.step(a).observation, 6);
    }
  }
  for (int i = 0; i < n; ++i) {
    // Inside +-2.5 (no input dominates the others), and spread over at least one unit (none is flattened).
    EXPECT_GE(low[i], -2.5) << "component " << i;
    EXPECT_LE(high[i], 2.5) << "component " << i;
    EXPECT_GE(high[i] - low[i], 1.0) << "component " << i;
  }
}

TEST(BlockPush, ToolStaysPlanarAndInsideTheWorkspace) {
  BlockPush env;
  env.reset(1);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  double worst_z = 0, worst_out = 0;
  for (int i = 0; i < BlockPush::kSteps; ++i) {
    env.step(Eigen::Vector2d(u(rng), u(rng)));
    const Eigen::Vector3d p = env.scene().arm().tool_pose().translation();
    worst_z = std::max(worst_z, std::abs(p.z() - BlockPush::kToolHeight));
    worst_out = std::max({worst_out, BlockPush::kXMin - p.x(), p.x() - BlockPush::kXMax,
                          BlockPush::kYMin - p.y(), p.y() - BlockPush::kYMax});
  }
  std::printf(
      "[block_push] 100 random steps: tool height error at most %.2e m, outside the workspace by at "
      "most %.2e m\n",
      worst_z, worst_out);
  EXPECT_LT(worst_z, 0.003);
  EXPECT_LT(worst_out, 0.005);
}

// A hand-written pusher: get behind the block (on the side away from the target, going round it), push it
// along the line to the target, stop when it is there.
Eigen::Vector2d scripted_push(const Eigen::VectorXd& o) {
  const Eigen::Vector2d b2t = o.segment<2>(3);
  const Eigen::Vector2d dir = b2t.normalized(), perp(-dir.y(), dir.x());
  const Eigen::Vector2d rel = -o.head<2>();  // the tool relative to the block
  const double along = rel.dot(dir), side = rel.dot(perp);
  Eigen::Vector2d v;  // m/s
  if (b2t.norm() < 0.01) {
    v.setZero();
  } else if (along < -0.03 && std::abs(side) < 0.012) {
    v = dir * std::min(0.25, 2.5 * b2t.norm() + 0.02) - 3.0 * side * perp;
  } else if (along < -0.05) {
    v = 4.0 * (-0.06 * dir - rel);
  } else {
    const double s = side >= 0 ? 1.0 : -1.0;
    v = 4.0 * (s * 0.07 * perp - 0.06 * dir - rel);
  }
  return (v / BlockPush::kSpeed).cwiseMax(-1.0).cwiseMin(1.0);
}

TEST(BlockPush, AScriptedPushSolvesEpisodes) {
  auto env = make_env("block_push");
  auto* push = dynamic_cast<BlockPush*>(env.get());
  ASSERT_NE(push, nullptr);
  int successes = 0;
  const int episodes = 10;
  for (int e = 0; e < episodes; ++e) {
    Eigen::VectorXd o = env->reset(100 + e);
    StepResult r;
    double ret = 0;
    do {
      r = env->step(scripted_push(o));
      o = r.observation;
      ret += r.reward;
    } while (!r.done());
    EXPECT_TRUE(r.truncated);
    EXPECT_EQ(env->elapsed_steps(), BlockPush::kSteps);
    successes += push->success();
    std::printf("[block_push] scripted episode %d: return %.1f, block %.3f m from the target, %s\n", e, ret,
                o.segment<2>(3).norm(), push->success() ? "success" : "miss");
  }
  EXPECT_GE(successes, 8);
}

}  // namespace
}  // namespace hlt::robot
