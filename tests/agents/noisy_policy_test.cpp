// NoisyPolicy (agents/policy_spec.h): a demonstrator whose executed actions vary around what it means to do.
// The noise must have the asked spread and stay in the action box, the intended action must be the noiseless
// one (the inner policy's own intended one where it has one), the same seed must repeat itself and a
// negative spread must be refused.
#include <gtest/gtest.h>

#include <cmath>

#include "agents/policy_spec.h"
#include "envs/registry.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

TEST(NoisyPolicy, AddsNoiseOfTheAskedSpreadInsideTheBoxAndKeepsTheNoiselessAction) {
  auto env = make_env("ant");
  const Eigen::VectorXd obs = env->reset(0);
  NoisyPolicy noisy(make_fixed_policy("constant:0", *env, 0, "test"), 0.3, 7);
  double sum = 0, squares = 0;
  int n = 0;
  for (int t = 0; t < 500; ++t) {
    const Eigen::VectorXd a = noisy.act(obs);
    ASSERT_EQ(a.size(), env->action_dim());
    ASSERT_TRUE(noisy.intended_action().has_value());
    EXPECT_EQ(*noisy.intended_action(), Eigen::VectorXd::Zero(env->action_dim()));
    EXPECT_LE(a.cwiseAbs().maxCoeff(), 1.0);
    sum += a.sum();
    squares += a.squaredNorm();
    n += static_cast<int>(a.size());
  }
  // 4000 draws of N(0, 0.3) (clipping at |x| > 1 removes 0.1 %): mean 0 +- 0.015, std 0.3 +- 0.01.
  const double mean = sum / n, std = std::sqrt(squares / n - mean * mean);
  EXPECT_NEAR(mean, 0.0, 0.015);
  EXPECT_NEAR(std, 0.3, 0.01);
  // Actions near the bound are clipped to it.
  NoisyPolicy near_bound(make_fixed_policy("constant:0.95", *env, 0, "test"), 0.5, 7);
  bool clipped = false;
  for (int t = 0; t < 20; ++t)
    clipped |= (near_bound.act(obs).array() == 1.0).any();
  EXPECT_TRUE(clipped);
  // The same seed repeats its noise; a spread of 0 changes nothing.
  NoisyPolicy a(make_fixed_policy("constant:0.2", *env, 0, "test"), 0.3, 11);
  NoisyPolicy b(make_fixed_policy("constant:0.2", *env, 0, "test"), 0.3, 11);
  EXPECT_EQ(a.act(obs), b.act(obs));
  NoisyPolicy none(make_fixed_policy("constant:0.2", *env, 0, "test"), 0.0, 11);
  EXPECT_EQ(none.act(obs), Eigen::VectorXd::Constant(env->action_dim(), 0.2));
  EXPECT_THROW(NoisyPolicy(make_fixed_policy("zero", *env, 0, "test"), -0.1, 0), Error);
}

TEST(NoisyPolicy, KeepsAScriptedExpertsOwnNoiselessAction) {
  // The stacking expert adds its own noise; its intended action stays the label under more noise.
  auto env = make_env("block_stack");
  const Eigen::VectorXd obs = env->reset(3);
  auto reference = make_fixed_policy("scripted:block_stack", *env, 5, "test");
  reference->act(obs);
  ASSERT_TRUE(reference->intended_action().has_value());
  NoisyPolicy noisy(make_fixed_policy("scripted:block_stack", *env, 5, "test"), 0.2, 1);
  const Eigen::VectorXd executed = noisy.act(obs);
  EXPECT_EQ(*noisy.intended_action(), *reference->intended_action());
  EXPECT_NE(executed, *reference->intended_action());
}

}  // namespace
}  // namespace hlt
