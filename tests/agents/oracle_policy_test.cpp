// OraclePolicy (agents/oracle_policy.h): MPPI on a copy of the environment. It must plan without touching
// the real environment, repeat itself for a seed, follow a frame skip, refuse malformed specs, and solve a
// problem whose answer is known (the pendulum swing-up, where doing nothing scores about -1270).
#include <gtest/gtest.h>

#include "agents/oracle_policy.h"
#include "agents/policy_spec.h"
#include "envs/registry.h"
#include "envs/rollout.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

TEST(OraclePolicy, SwingsThePendulumUp) {
  auto env = make_env("pendulum");
  auto zero = make_fixed_policy("zero", *env, 0, "--policy");
  auto oracle = make_fixed_policy("oracle:20,20,1,0.5", *env, 0, "--policy");
  double zero_return = 0, oracle_return = 0;
  for (uint64_t seed = 0; seed < 3; ++seed) {
    zero_return += run_episode(*env, *zero, seed).episode_return / 3;
    oracle_return += run_episode(*env, *oracle, seed).episode_return / 3;
  }
  // Measured: zero -1267, oracle -215 (a swing-up and balance in each episode).
  EXPECT_LT(zero_return, -900);
  EXPECT_GT(oracle_return, -400);
}

TEST(OraclePolicy, PlansWithoutTouchingTheRealEnvironment) {
  auto env = make_env("cartpole_swingup");
  OraclePolicy oracle(*env, OracleOptions{5, 4, 0.1, 0.5}, 1);
  Eigen::VectorXd o = env->reset(3);
  for (int t = 0; t < 3; ++t) {
    const EnvState before = env->save_state();
    const Eigen::VectorXd a = oracle.act(o);
    const EnvState after = env->save_state();
    EXPECT_EQ(after.sim, before.sim);
    EXPECT_EQ(after.elapsed_steps, before.elapsed_steps);
    EXPECT_TRUE(after.rng == before.rng);
    EXPECT_EQ(a.size(), env->action_dim());
    EXPECT_LE(a.cwiseAbs().maxCoeff(), 1.0);
    o = env->step(a).observation;
  }
}

TEST(OraclePolicy, SameSeedSameActionsAndFollowsAFrameSkip) {
  auto make = [] { return std::make_unique<FrameSkip>(make_env("pendulum"), 3); };
  std::vector<Eigen::VectorXd> first;
  for (int run = 0; run < 2; ++run) {
    auto env = make();
    OraclePolicy oracle(*env, OracleOptions{4, 6, 1.0, 0.5}, 7);
    Eigen::VectorXd o = env->reset(2);
    for (int t = 0; t < 5; ++t) {
      const Eigen::VectorXd a = oracle.act(o);
      if (run == 0)
        first.push_back(a);
      else
        EXPECT_EQ(a, first[static_cast<size_t>(t)]) << "step " << t;
      o = env->step(a).observation;
    }
  }
}

TEST(OraclePolicy, RefusesMalformedSpecs) {
  for (const char* bad : {"10", "10,x", "0,10", "10,10,-1", "10,10,0.1,0.5,3", "10,10,nan", "10.5,10", ""})
    EXPECT_THROW(OraclePolicy::parse(bad), Error) << bad;
  const OracleOptions o = OraclePolicy::parse("12,30,0.5,0.3");
  EXPECT_EQ(o.horizon, 12);
  EXPECT_EQ(o.samples, 30);
  EXPECT_DOUBLE_EQ(o.lambda, 0.5);
  EXPECT_DOUBLE_EQ(o.noise, 0.3);
  auto env = make_env("pendulum");
  EXPECT_THROW(make_fixed_policy("oracle:5", *env, 0, "--policy"), Error);
}

}  // namespace
}  // namespace hlt
