#include "envs/rollout.h"

#include <gtest/gtest.h>

#include "envs/registry.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

TEST(Rollout, SimplePolicies) {
  const Eigen::VectorXd obs = Eigen::VectorXd::Zero(3);
  EXPECT_EQ(make_simple_policy("zero", 2, 0)->act(obs), Eigen::VectorXd::Zero(2));
  EXPECT_EQ(make_simple_policy("constant:0.5", 3, 0)->act(obs), Eigen::VectorXd::Constant(3, 0.5));
  EXPECT_EQ(make_simple_policy("constant:0.1,-0.2", 2, 0)->act(obs), Eigen::Vector2d(0.1, -0.2));
  auto a = make_simple_policy("random", 4, 9), b = make_simple_policy("random", 4, 9);
  for (int i = 0; i < 100; ++i) {
    const Eigen::VectorXd x = a->act(obs);
    EXPECT_EQ(x, b->act(obs));
    EXPECT_LE(x.cwiseAbs().maxCoeff(), 1.0);
  }
  for (const char* bad :
       {"", "zeros", "constant:", "constant:x", "constant:1,2,3", "constant:nan", "checkpoint:a"}) {
    EXPECT_THROW(make_simple_policy(bad, 2, 0), Error) << bad;
  }
}

TEST(Rollout, EpisodeLoopAndSummary) {
  auto env = make_env("pendulum");
  auto policy = make_simple_policy("constant:0.3", 1, 0);
  int seen = 0;
  Eigen::VectorXd first_obs;
  double sum = 0;
  const EpisodeStats s = run_episode(*env, *policy, 4, [&](const Transition& t) {
    if (t.step == 0) first_obs = t.observation;
    EXPECT_EQ(t.step, seen);
    EXPECT_EQ(t.action[0], 0.3);
    sum += t.result.reward;
    ++seen;
  });
  EXPECT_EQ(s.length, 200);
  EXPECT_EQ(seen, 200);
  EXPECT_TRUE(s.truncated);
  EXPECT_FALSE(s.terminated);
  EXPECT_DOUBLE_EQ(s.episode_return, sum);
  EXPECT_EQ(first_obs, env->reset(4));  // the transition carries the observation the action was chosen from

  std::vector<EpisodeStats> eps(3);
  eps[0].episode_return = 1;
  eps[1].episode_return = 2;
  eps[2].episode_return = 6;
  eps[0].length = eps[1].length = 10;
  eps[2].length = 1;
  const ReturnSummary r = summarize(eps);
  EXPECT_DOUBLE_EQ(r.mean_return, 3.0);
  EXPECT_NEAR(r.std_return, std::sqrt(14.0 / 3.0), 1e-12);
  EXPECT_DOUBLE_EQ(r.mean_length, 7.0);
  EXPECT_FALSE(r.success_rate);  // no task criterion: no rate
  EXPECT_FALSE(s.success);       // the pendulum has none
  eps[0].success = true;
  eps[1].success = false;
  eps[2].success = true;
  EXPECT_DOUBLE_EQ(*summarize(eps).success_rate, 2.0 / 3.0);
  eps[1].success.reset();  // only episodes with a verdict count
  EXPECT_DOUBLE_EQ(*summarize(eps).success_rate, 1.0);
}

TEST(Rollout, TheEpisodeLoopReportsTheTasksSuccessAtTheEnd) {
  // The scripted stacking expert succeeds on most starts (block_stack_test); the zero policy never stacks.
  auto env = make_env("block_stack");
  ASSERT_TRUE(env->episode_success().has_value());
  auto expert = make_policy_for("scripted:block_stack", *env, 0);
  auto zero = make_simple_policy("zero", env->action_dim(), 0);
  int expert_successes = 0;
  for (uint64_t seed = 0; seed < 3; ++seed) {
    const EpisodeStats s = run_episode(*env, *expert, seed);
    ASSERT_TRUE(s.success.has_value());
    EXPECT_EQ(*s.success, *env->episode_success());  // the verdict of the final state
    expert_successes += *s.success;
    const EpisodeStats z = run_episode(*env, *zero, seed);
    ASSERT_TRUE(z.success.has_value());
    EXPECT_FALSE(*z.success);
  }
  EXPECT_GE(expert_successes, 2);
  // A frame-skip wrapper forwards the verdict.
  FrameSkip skipped(make_env("block_push"), 2);
  EXPECT_TRUE(skipped.episode_success().has_value());
}

}  // namespace
}  // namespace hlt
