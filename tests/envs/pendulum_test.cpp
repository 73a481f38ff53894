#include "envs/pendulum.h"

#include <gtest/gtest.h>

#include <cmath>

namespace hlt {
namespace {

constexpr double kPi = 3.14159265358979323846;

// gym Pendulum-v0, written out independently of the environment: one step from (th, thd) under agent
// action a. Returns {theta', thetad', reward}.
struct Expected {
  double theta, theta_dot, reward;
};
Expected gym_step(double th, double thd, double a) {
  const double u = std::fmax(-2.0, std::fmin(2.0, 2.0 * a));
  // angle_normalize(x) = ((x + pi) % (2 pi)) - pi with Python's non-negative modulo.
  double n = std::fmod(th + kPi, 2 * kPi);
  if (n < 0) n += 2 * kPi;
  n -= kPi;
  const double cost = n * n + 0.1 * thd * thd + 0.001 * u * u;
  double new_thd = thd + (-3 * 10.0 / 2 * std::sin(th + kPi) + 3.0 * u) * 0.05;
  const double new_th = th + new_thd * 0.05;
  new_thd = std::fmax(-8.0, std::fmin(8.0, new_thd));
  return {new_th, new_thd, -cost};
}

TEST(Pendulum, OneStepMatchesClosedForm) {
  Pendulum env;
  env.reset(0);
  const double states[][2] = {{0.0, 0.0}, {0.3, -0.7},   {kPi, 0.0}, {-2.5, 3.0},
                              {7.0, 7.9}, {-9.5, -7.95}, {1.0, 7.99}};
  const double actions[] = {0.0, 0.25, -1.0, 1.0, 3.0, -5.0};  // beyond [-1, 1]: the torque clips at 2
  for (const auto& s : states) {
    for (double a : actions) {
      env.set_state(s[0], s[1]);
      const StepResult r = env.step(Eigen::VectorXd::Constant(1, a));
      const Expected e = gym_step(s[0], s[1], a);
      SCOPED_TRACE(testing::Message() << "theta " << s[0] << " thetad " << s[1] << " a " << a);
      EXPECT_DOUBLE_EQ(env.theta(), e.theta);
      EXPECT_DOUBLE_EQ(env.theta_dot(), e.theta_dot);
      EXPECT_DOUBLE_EQ(r.reward, e.reward);
      EXPECT_DOUBLE_EQ(r.observation[0], std::cos(e.theta));
      EXPECT_DOUBLE_EQ(r.observation[1], std::sin(e.theta));
      EXPECT_DOUBLE_EQ(r.observation[2], e.theta_dot);
      EXPECT_FALSE(r.done());
    }
  }
}

TEST(Pendulum, HandComputedValues) {
  Pendulum env;
  env.reset(0);
  // Hanging down at rest with full positive torque: thetad' = (-15 sin(2 pi) + 6) * 0.05 = 0.3;
  // reward = -(pi^2 (wrapped to -pi) + 0.001 * 4).
  env.set_state(kPi, 0.0);
  const StepResult r = env.step(Eigen::VectorXd::Constant(1, 1.0));
  EXPECT_NEAR(env.theta_dot(), 0.3, 1e-12);
  EXPECT_NEAR(env.theta(), kPi + 0.015, 1e-12);
  EXPECT_NEAR(r.reward, -(kPi * kPi + 0.004), 1e-12);
  // The speed clips at 8, but the position moved with the unclipped speed.
  env.set_state(0.5, 8.0);
  env.step(Eigen::VectorXd::Constant(1, 1.0));
  const double unclipped = 8.0 + (15 * std::sin(0.5) + 6) * 0.05;
  EXPECT_EQ(env.theta_dot(), 8.0);
  EXPECT_NEAR(env.theta(), 0.5 + unclipped * 0.05, 1e-12);
}

TEST(Pendulum, ResetDistributionAndLimit) {
  Pendulum env;
  for (uint64_t seed = 0; seed < 200; ++seed) {
    const Eigen::VectorXd obs = env.reset(seed);
    EXPECT_NEAR(obs[0] * obs[0] + obs[1] * obs[1], 1.0, 1e-12);
    EXPECT_GE(env.theta(), -kPi);
    EXPECT_LT(env.theta(), kPi);
    EXPECT_GE(obs[2], -1.0);
    EXPECT_LT(obs[2], 1.0);
  }
  env.reset(1);
  int steps = 0;
  StepResult r;
  do {
    r = env.step(Eigen::VectorXd::Zero(1));
    ++steps;
  } while (!r.done());
  EXPECT_EQ(steps, 200);
  EXPECT_TRUE(r.truncated);
  EXPECT_FALSE(r.terminated);
}

}  // namespace
}  // namespace hlt
