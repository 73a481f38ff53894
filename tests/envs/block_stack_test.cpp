// The block-stacking task (envs/robot/block_stack.h) and its scripted expert (block_stack_expert.h): reward
// and stages against hand-computed values, the gripper command, the success check, the reset distribution,
// exact snapshots while a block is held, and the expert stacking in at least 9 of 10 episodes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "envs/registry.h"
#include "envs/robot/block_stack.h"
#include "envs/robot/block_stack_expert.h"
#include "envs/rollout.h"
#include "envs/scripted.h"
#include "hlt/util/error.h"

namespace hlt::robot {
namespace {

using B = BlockStack;

Eigen::VectorXd obs(const Eigen::Vector3d& ee, const Eigen::Vector3d& block, const Eigen::Vector3d& base,
                    double opening_fraction, const Eigen::Vector3d& force = Eigen::Vector3d::Zero()) {
  Eigen::VectorXd o = Eigen::VectorXd::Zero(B::kObsDim);
  o.segment<3>(B::kEe) = ee;
  o.segment<3>(B::kBlock) = block;
  o.segment<3>(B::kBase) = base;
  o[B::kGripper] = opening_fraction;
  o.segment<3>(B::kForce) = force;
  o.segment<3>(B::kTorque) = Eigen::Vector3d(0.1, -0.2, 0.3);  // the torque costs nothing
  return o;
}

TEST(BlockStack, RewardMatchesHandComputedValues) {
  const Eigen::Vector3d base(0.5, 0.12, 0.025);  // stack point (0.5, 0.12, 0.075)
  // Reaching, fingers open: |ee - block| = 0.08, |block - stack| = |(0, -0.12, -0.05)| = 0.13.
  const Eigen::VectorXd reach = obs({0.5, 0, 0.105}, {0.5, 0, 0.025}, base, 1.0, {3, 0, 4});
  EXPECT_FALSE(B::grasped(reach));
  EXPECT_NEAR(B::stage_reward(reach), -0.08 - 1.25 * 0.13, 1e-12);
  // |F| = 5, |a| = 1: -1e-6 * 6 more.
  EXPECT_NEAR(B::reward(reach, Eigen::Vector4d(0.6, 0, 0.8, 0)), -0.2425 - 6e-6, 1e-12);

  // Carrying: fingers closed to 2.5 cm on the block, |ee - stack| = |(0, -0.12, -0.05)| = 0.13.
  const Eigen::VectorXd carry = obs({0.5, 0, 0.025}, {0.5, 0.003, 0.02}, base, 0.625);
  EXPECT_TRUE(B::grasped(carry));
  EXPECT_EQ(B::stage(carry), B::Stage::kCarry);
  EXPECT_NEAR(B::stage_reward(carry), -1.25 * 0.13, 1e-12);
  EXPECT_NEAR(B::reward(carry, Eigen::Vector4d::Zero()), -0.1625, 1e-12);

  // At the moment of the grasp (tool centre at the block's) the two stages agree: grasping costs nothing.
  const Eigen::Vector3d p(0.45, -0.1, 0.025);
  const Eigen::VectorXd open_at = obs(p, p, base, 1.0), closed_at = obs(p, p, base, 0.625);
  EXPECT_EQ(B::stage(open_at), B::Stage::kReach);
  EXPECT_EQ(B::stage(closed_at), B::Stage::kCarry);
  EXPECT_NEAR(B::stage_reward(open_at), B::stage_reward(closed_at), 1e-12);
  // Stacked and let go, the tool 4 cm over the block: only the paper's -|p_ee - p_block| is left.
  const Eigen::Vector3d top = B::stack_point(open_at);
  EXPECT_NEAR(B::stage_reward(obs(top + Eigen::Vector3d(0, 0, 0.04), top, base, 1.0)), -0.04, 1e-12);
}

TEST(BlockStack, GraspNeedsClosedFingersAroundTheBlock) {
  const Eigen::Vector3d base(0.6, 0.1, 0.025), ee(0.5, -0.1, 0.03), block(0.5, -0.1, 0.025);
  // Closed on the 5 cm block: 0.025 m each (fraction 0.625), a little less when squeezed.
  EXPECT_TRUE(B::grasped(obs(ee, block, base, 0.625)));
  EXPECT_TRUE(B::grasped(obs(ee, block, base, 0.5)));
  // Open (3 cm each), closed on nothing, or closed beside the block.
  EXPECT_FALSE(B::grasped(obs(ee, block, base, 0.75)));
  EXPECT_FALSE(B::grasped(obs(ee, block, base, 0.0)));
  EXPECT_FALSE(B::grasped(obs(ee, block + Eigen::Vector3d(0, 0.02, 0), base, 0.625)));
  EXPECT_FALSE(B::grasped(obs(ee, block + Eigen::Vector3d(0.025, 0, 0), base, 0.625)));
  // The block under the fingertips, or above the pads.
  EXPECT_FALSE(B::grasped(obs(ee, block - Eigen::Vector3d(0, 0, 0.03), base, 0.625)));
  EXPECT_FALSE(B::grasped(obs(ee, block + Eigen::Vector3d(0, 0, 0.03), base, 0.625)));
  EXPECT_THROW(B::grasped(Eigen::VectorXd::Zero(5)), Error);
}

TEST(BlockStack, ObservationAndStepRewardComeFromTheScene) {
  B env;
  env.reset(0);
  env.place({0.5, -0.1, 0.0}, {0.6, 0.15, 0.3});
  // An action beyond [-1, 1] is clipped before it moves the tool or costs reward.
  const Eigen::Vector3d before = env.scene().arm().tool_pose().translation();
  const StepResult r = env.step(Eigen::Vector4d(0.0, 3.0, -0.5, -2.0));
  const Eigen::VectorXd& o = r.observation;
  const Eigen::Vector3d ee = env.scene().arm().tool_pose().translation();
  EXPECT_EQ(o.size(), B::kObsDim);
  EXPECT_EQ(Eigen::Vector3d(o.segment<3>(B::kEe)), ee);
  EXPECT_EQ(Eigen::Vector3d(o.segment<3>(B::kBlock)), env.scene().block_pose(0).translation());
  EXPECT_EQ(Eigen::Vector3d(o.segment<3>(B::kBase)), env.scene().block_pose(1).translation());
  EXPECT_NEAR(o[B::kGripper], 1.0, 1e-3);  // opening further stays at the stop
  EXPECT_NEAR(r.reward, B::reward(o, Eigen::Vector4d(0.0, 1.0, -0.5, -1.0)), 1e-15);
  // 0.1 s at (0, 0.15, -0.075) m/s from rest: most of the way.
  EXPECT_NEAR(ee.y() - before.y(), 0.015, 0.002);
  EXPECT_NEAR(ee.z() - before.z(), -0.0075, 0.001);
  // Held still in the air, nothing but the hand's weight acts on the wrist: no external force.
  for (int i = 0; i < 5; ++i)
    env.step(Eigen::Vector4d::Zero());
  EXPECT_LT(env.external_force().norm(), 0.02);
  // The gripper is binary: any command > 0 closes the fingers at full speed (0.2 m/s: 2 cm of their 4 in a
  // step), any command <= 0 opens them at full speed.
  env.step(Eigen::Vector4d(0, 0, 0, 0.1));
  EXPECT_NEAR(env.observation()[B::kGripper], 0.5, 0.05);
  env.step(Eigen::Vector4d(0, 0, 0, 0.1));
  EXPECT_NEAR(env.observation()[B::kGripper], 0.0, 0.05);
  env.step(Eigen::Vector4d(0, 0, 0, -0.1));
  EXPECT_NEAR(env.observation()[B::kGripper], 0.5, 0.05);
  env.step(Eigen::Vector4d(0, 0, 0, 0.0));
  EXPECT_NEAR(env.observation()[B::kGripper], 1.0, 0.05);
}

TEST(BlockStack, FirstObservationReadsTheRestingWrench) {
  // Before any step the wrist has measured nothing; the first observation must still read what the wrist
  // reads at rest (no external force, no torque), as it does after steps held still.
  B env;
  const Eigen::VectorXd first = env.reset(3);
  EXPECT_LT(first.segment<3>(B::kForce).norm(), 1e-9);
  EXPECT_LT(first.segment<3>(B::kTorque).norm(), 1e-9);
  Eigen::VectorXd still;
  for (int i = 0; i < 5; ++i)
    still = env.step(Eigen::Vector4d(0, 0, 0, -1)).observation;
  EXPECT_LT((still.segment<3>(B::kForce) - first.segment<3>(B::kForce)).norm(), 0.05);
  EXPECT_LT((still.segment<3>(B::kTorque) - first.segment<3>(B::kTorque)).norm(), 0.005);
}

TEST(BlockStack, SuccessIsTheBlockRestingOnTheBaseReleased) {
  B env;
  env.reset(0);
  const Eigen::Vector3d base(0.6, 0.1, 0.4);  // x, y, yaw
  const auto settle = [&](double grip) {
    for (int i = 0; i < 5; ++i)
      env.step(Eigen::Vector4d(0, 0, 0, grip));
  };
  // On the base, centred, the fingers open: a success.
  env.place({0.45, -0.1, 0.0}, base);
  env.scene().set_block(0, {0.6, 0.1, 0.075}, 0.1);
  settle(-1.0);
  EXPECT_TRUE(env.success());
  // Off centre by 1.2 cm still, by 2 cm not (it still rests on the base, a 5 cm cube).
  env.place({0.45, -0.1, 0.0}, base);
  env.scene().set_block(0, {0.612, 0.1, 0.075}, 0.0);
  settle(-1.0);
  EXPECT_TRUE(env.success());
  env.place({0.45, -0.1, 0.0}, base);
  env.scene().set_block(0, {0.6, 0.12, 0.075}, 0.0);
  settle(-1.0);
  EXPECT_NEAR(env.scene().block_pose(0).translation().z(), 0.075, 0.002);
  EXPECT_FALSE(env.success());
  // Beside the base on the table.
  env.place({0.45, -0.1, 0.0}, base);
  EXPECT_FALSE(env.success());
  // Held on the base by closed fingers: not yet (the expert's run up to its release).
  env.reset(3);
  StackExpert expert(0, 0.0);
  Eigen::VectorXd o = env.observation();
  int steps = 0;
  while (StackExpert::phase(o) != StackExpert::Phase::kRelease && steps < B::kSteps - 1) {
    o = env.step(expert.act(o)).observation;
    ++steps;
  }
  ASSERT_EQ(StackExpert::phase(o), StackExpert::Phase::kRelease) << "after " << steps << " steps";
  EXPECT_TRUE(B::grasped(o));
  const Eigen::Vector3d b = o.segment<3>(B::kBlock), s = B::stack_point(o);
  EXPECT_LT((b - s).norm(), 0.01);
  EXPECT_FALSE(env.success());
  // Let go: now it is.
  settle(-1.0);
  EXPECT_TRUE(env.success());
}

TEST(BlockStack, ResetPlacesTheBlocksInTheirRanges) {
  B env;
  for (uint64_t seed = 0; seed < 50; ++seed) {
    const Eigen::VectorXd o = env.reset(seed);
    const Eigen::Vector3d block = env.scene().block_pose(0).translation();
    const Eigen::Vector3d base = env.scene().block_pose(1).translation();
    EXPECT_LE(std::abs(block.x() - B::kBlockX), B::kJitter);
    EXPECT_LE(std::abs(block.y() - B::kBlockY), B::kJitter);
    EXPECT_LE(std::abs(yaw_of(env.scene().block_pose(0))), 0.05 + 1e-9);
    EXPECT_LE(std::abs(base.x() - B::kBaseX), B::kJitter);
    EXPECT_LE(std::abs(base.y() - B::kBaseY), B::kJitter);
    EXPECT_NEAR(block.z(), B::kBlockHalf, 1e-12);
    EXPECT_NEAR(base.z(), B::kBlockHalf, 1e-12);
    // The gripper open over the block's spot, the same start every episode.
    const Eigen::Vector3d ee = o.segment<3>(B::kEe);
    EXPECT_NEAR((ee - Eigen::Vector3d(B::kBlockX, B::kBlockY, B::kStartHeight)).norm(), 0, 1e-4);
    EXPECT_NEAR(o[B::kGripper], 1.0, 1e-12);
    EXPECT_EQ(B::stage(o), B::Stage::kReach);
    EXPECT_FALSE(env.success());
  }
}

TEST(BlockStack, SnapshotWhileHoldingTheBlockIsExact) {
  auto env = make_env("block_stack");
  auto policy = make_policy_for("scripted:block_stack", *env, 5);
  Eigen::VectorXd o = env->reset(2);
  while ((B::stage(o) != B::Stage::kCarry || o[B::kBlock + 2] < 0.05) && env->elapsed_steps() < 150)
    o = env->step(policy->act(o)).observation;
  ASSERT_LT(env->elapsed_steps(), 100);
  const EnvState snap = env->save_state();
  std::vector<Eigen::VectorXd> first;
  auto run = [&](Env& e, Eigen::VectorXd x) {
    std::vector<Eigen::VectorXd> out;
    robot::StackExpert expert(11);
    for (int i = 0; i < 40; ++i) {
      x = e.step(expert.act(x)).observation;
      out.push_back(x);
    }
    return out;
  };
  first = run(*env, o);
  env->restore_state(snap);
  EXPECT_EQ(run(*env, o), first);
  auto fresh = make_env("block_stack");
  fresh->restore_state(snap);
  EXPECT_EQ(run(*fresh, o), first);
}

TEST(BlockStack, ScriptedPolicyIsRegisteredForThisEnvironmentOnly) {
  const std::vector<std::string> names = scripted_policy_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "block_stack"), names.end());
  auto stack = make_env("block_stack");
  auto push = make_env("block_push");
  EXPECT_NE(make_policy_for("scripted:block_stack", *stack, 0)->describe().find("block_stack"),
            std::string::npos);
  EXPECT_THROW(make_policy_for("scripted:block_stack", *push, 0), Error);
  EXPECT_THROW(make_policy_for("scripted:nothing", *stack, 0), Error);
  EXPECT_THROW(make_policy_for("scripts", *stack, 0), Error);
  EXPECT_EQ(make_policy_for("zero", *stack, 0)->act(Eigen::VectorXd::Zero(16)), Eigen::VectorXd::Zero(4));
  // The same seed, the same noise.
  auto a = make_policy_for("scripted:block_stack", *stack, 3),
       b = make_policy_for("scripted:block_stack", *stack, 3);
  const Eigen::VectorXd o = stack->reset(0);
  for (int i = 0; i < 5; ++i)
    EXPECT_EQ(a->act(o), b->act(o));
}

TEST(BlockStack, ScriptedExpertLabelsItsStepsWithTheNoiselessAction) {
  auto env = make_env("block_stack");
  auto expert = make_policy_for("scripted:block_stack", *env, 5);
  EXPECT_FALSE(expert->intended_action().has_value());  // nothing asked yet
  Eigen::VectorXd o = env->reset(1);
  double largest_noise = 0;
  for (int i = 0; i < 30; ++i) {
    const Eigen::VectorXd a = expert->act(o);
    ASSERT_TRUE(expert->intended_action().has_value());
    const Eigen::VectorXd label = *expert->intended_action();
    EXPECT_EQ(label, Eigen::VectorXd(StackExpert::nominal_action(o)));
    largest_noise = std::max(largest_noise, (a - label).cwiseAbs().maxCoeff());
    o = env->step(a).observation;
  }
  // The executed actions carry the noise (standard deviation 0.1), the labels do not.
  EXPECT_GT(largest_noise, 0.1);
  // Policies that add no noise have no separate label.
  EXPECT_FALSE(make_policy_for("zero", *env, 0)->intended_action().has_value());
}

TEST(BlockStack, ScriptedExpertGradesItsGripperCommandTowardsTheSwitch) {
  // Noiseless: the descent's command rises from -1 towards the grasp and the lowering's falls from +1
  // towards the release, staying on the side of the sign the environment acts on, then switches.
  B env;
  Eigen::VectorXd o = env.reset(4);
  std::vector<std::pair<StackExpert::Phase, double>> run;
  for (int t = 0; t < B::kSteps; ++t) {
    const Eigen::Vector4d a = StackExpert::nominal_action(o);
    run.emplace_back(StackExpert::phase(o), a[3]);
    o = env.step(a).observation;
  }
  auto check_ramp = [&](StackExpert::Phase ramp, StackExpert::Phase next, double sign) {
    std::vector<double> labels;
    size_t i = 0;
    while (i < run.size() && run[i].first != ramp)
      ++i;
    for (; i < run.size() && run[i].first == ramp; ++i)
      labels.push_back(sign * run[i].second);
    ASSERT_GE(labels.size(), 3u);
    ASSERT_LT(i, run.size());
    EXPECT_EQ(run[i].first, next);
    EXPECT_EQ(sign * run[i].second, -1.0);  // switched: the other sign, fully
    EXPECT_GT(labels.front(), 0.9);         // starts far from the switch
    for (size_t k = 1; k < labels.size(); ++k) {
      EXPECT_LE(labels[k], labels[k - 1]) << k;
      EXPECT_GE(labels[k], 0.2) << k;
    }
    EXPECT_LT(labels.back(), 0.6);  // graded: close to the switch just before it
  };
  check_ramp(StackExpert::Phase::kDescend, StackExpert::Phase::kClose, -1.0);
  check_ramp(StackExpert::Phase::kLower, StackExpert::Phase::kRelease, 1.0);
}

TEST(BlockStack, ScriptedExpertStacksInNineOfTenEpisodes) {
  auto env = make_env("block_stack");
  auto* stack = dynamic_cast<B*>(env.get());
  ASSERT_NE(stack, nullptr);
  int successes = 0;
  for (uint64_t seed = 0; seed < 10; ++seed) {
    auto policy = make_policy_for("scripted:block_stack", *env, 1000 + seed);
    int released_at = -1;
    const EpisodeStats s = run_episode(*env, *policy, seed, [&](const Transition& t) {
      if (released_at < 0 && StackExpert::phase(t.result.observation) == StackExpert::Phase::kRetreat)
        released_at = t.step;
    });
    EXPECT_TRUE(s.truncated);
    EXPECT_EQ(s.length, B::kSteps);
    const bool ok = stack->success();
    successes += ok;
    const Eigen::Vector3d b = stack->scene().block_pose(0).translation();
    const Eigen::Vector3d base = stack->scene().block_pose(1).translation();
    std::printf(
        "[block_stack] scripted episode %d: return %.2f, released after %d steps, block centre %.1f mm from "
        "the base's axis, %.1f mm off the stacking height: %s\n",
        static_cast<int>(seed), s.episode_return, released_at + 1, 1000 * (b - base).head<2>().norm(),
        1000 * (b.z() - base.z() - 2 * B::kBlockHalf), ok ? "success" : "miss");
  }
  EXPECT_GE(successes, 9);
}

}  // namespace
}  // namespace hlt::robot
