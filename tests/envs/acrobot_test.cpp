#include "envs/acrobot.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include <Eigen/Dense>

namespace hlt {
namespace {

using State = Acrobot::State;
constexpr double kG = 9.8;

// The acrobot written independently, from its Lagrangian: M(q) qdd + C(q, qd) + G(q) = [0, tau], with unit
// masses and lengths, COMs at 0.5 and unit inertias about the COMs.
State lagrangian_derivative(const State& s, double tau) {
  const double t1 = s[0], t2 = s[1], w1 = s[2], w2 = s[3];
  const double c2 = std::cos(t2), s2 = std::sin(t2);
  Eigen::Matrix2d mass;
  mass(0, 0) = 0.25 + 1.0 + (1.0 + 0.25 + c2) + 1.0;  // m1 lc1^2 + I1 + m2 (l1^2 + lc2^2 + 2 l1 lc2 c2) + I2
  mass(0, 1) = mass(1, 0) = 0.25 + 0.5 * c2 + 1.0;
  mass(1, 1) = 0.25 + 1.0;
  const double h = 0.5 * s2;  // m2 l1 lc2 sin(t2)
  const Eigen::Vector2d coriolis(-h * (2 * w1 * w2 + w2 * w2), h * w1 * w1);
  // Potential V = -(m1 lc1 + m2 l1) g cos t1 - m2 lc2 g cos(t1 + t2) (zero angles hang down).
  const Eigen::Vector2d gravity(1.5 * kG * std::sin(t1) + 0.5 * kG * std::sin(t1 + t2),
                                0.5 * kG * std::sin(t1 + t2));
  const Eigen::Vector2d qdd = mass.ldlt().solve(Eigen::Vector2d(0, tau) - coriolis - gravity);
  return {w1, w2, qdd[0], qdd[1]};
}

State hand_rk4(const State& s, double tau, double h) {
  const State k1 = lagrangian_derivative(s, tau);
  const State k2 = lagrangian_derivative(s + h / 2 * k1, tau);
  const State k3 = lagrangian_derivative(s + h / 2 * k2, tau);
  const State k4 = lagrangian_derivative(s + h * k3, tau);
  return s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
}

double energy(const State& s) {
  const double t1 = s[0], t2 = s[1], w1 = s[2], w2 = s[3];
  const double kinetic =
      0.5 * (0.25 + 1.0) * w1 * w1 +
      0.5 * (1.0 * w1 * w1 + 0.25 * (w1 + w2) * (w1 + w2) + std::cos(t2) * w1 * (w1 + w2)) +
      0.5 * 1.0 * (w1 + w2) * (w1 + w2);
  return kinetic - 1.5 * kG * std::cos(t1) - 0.5 * kG * std::cos(t1 + t2);
}

const State kStates[] = {State(0, 0, 0, 0), State(0.3, -0.2, 1.0, -2.0), State(3.0, 1.0, -4.0, 6.0),
                         State(-2.0, 2.5, 7.0, -9.0), State(10.0, -7.0, 0.5, 0.1)};

TEST(Acrobot, EquationsOfMotionMatchTheLagrangian) {
  for (const State& s : kStates) {
    for (double tau : {0.0, 1.0, -0.4}) {
      const State a = Acrobot::derivative(s, tau), b = lagrangian_derivative(s, tau);
      for (int i = 0; i < 4; ++i)
        EXPECT_NEAR(a[i], b[i], 1e-12 * (1 + std::abs(b[i]))) << s.transpose();
    }
  }
}

TEST(Acrobot, OneStepIsOneRk4StepOf02Seconds) {
  Acrobot env;
  env.reset(0);
  for (const State& s : kStates) {
    for (double a : {0.0, 0.7, -1.0, 2.5}) {
      env.set_state(s);
      const StepResult r = env.step(Eigen::VectorXd::Constant(1, a));
      const double tau = std::fmax(-1.0, std::fmin(1.0, a));
      const State expected = hand_rk4(s, tau, 0.2);
      for (int i = 0; i < 4; ++i)
        EXPECT_NEAR(env.state()[i], expected[i], 1e-12 * (1 + std::abs(expected[i])));
      EXPECT_DOUBLE_EQ(r.reward, -(0.001 * tau * tau + std::cos(s[0]) + std::cos(s[0] + s[1])));
      EXPECT_DOUBLE_EQ(r.observation[0], std::cos(env.state()[0]));
      EXPECT_DOUBLE_EQ(r.observation[3], std::sin(env.state()[1]));
      EXPECT_DOUBLE_EQ(r.observation[5], env.state()[3]);
      if (r.done()) env.reset();
    }
  }
}

TEST(Acrobot, EnergyIsNearlyConservedWithoutTorque) {
  Acrobot env;
  env.reset(0);
  env.set_state(State(1.0, -0.5, 0.0, 0.0));
  const double e0 = energy(env.state());
  double worst = 0;
  for (int i = 0; i < 50; ++i) {  // 10 s
    const StepResult r = env.step(Eigen::VectorXd::Zero(1));
    worst = std::max(worst, std::abs(energy(env.state()) - e0));
    ASSERT_FALSE(r.done());
  }
  std::cout << "  acrobot, 10 s without torque from (1, -0.5): energy " << e0 << " J, largest RK4 drift "
            << worst << " J\n";
  EXPECT_LT(worst, 0.01 * std::abs(e0));
}

TEST(Acrobot, TerminatesWhenTheTipRisesAbove15) {
  Acrobot env;
  env.reset(0);
  // Nearly upright and rising slowly: height -cos(2.6) - cos(2.6) = 1.71 > 1.5.
  env.set_state(State(2.6, 0.0, 0.0, 0.0));
  StepResult r = env.step(Eigen::VectorXd::Zero(1));
  EXPECT_GT(env.tip_height(), 1.5);
  EXPECT_TRUE(r.terminated);
  EXPECT_FALSE(r.truncated);
  // Below the line: not done.
  env.reset(0);
  env.set_state(State(1.0, 0.0, 0.0, 0.0));
  r = env.step(Eigen::VectorXd::Zero(1));
  EXPECT_LT(env.tip_height(), 1.5);
  EXPECT_FALSE(r.done());
}

TEST(Acrobot, ResetRangeAndTimeLimit) {
  Acrobot env;
  for (uint64_t seed = 0; seed < 50; ++seed) {
    env.reset(seed);
    for (int i = 0; i < 4; ++i) {
      EXPECT_GE(env.state()[i], -0.1);
      EXPECT_LT(env.state()[i], 0.1);
    }
  }
  env.reset(1);
  double ret = 0;
  int steps = 0;
  StepResult r;
  do {
    r = env.step(Eigen::VectorXd::Zero(1));
    ret += r.reward;
    ++steps;
  } while (!r.done());
  std::cout << "  acrobot zero-action return, seed 1: " << ret << " over " << steps << " steps\n";
  EXPECT_EQ(steps, 500);
  EXPECT_TRUE(r.truncated);
  EXPECT_FALSE(r.terminated);
  EXPECT_NEAR(ret, -1000.0, 10.0);  // hanging down the whole time: reward about -2 per step
}

TEST(Acrobot, NonFiniteStateEndsTheEpisode) {
  Acrobot env;
  env.reset(0);
  env.set_state(State(0.0, 0.5, 1e200, -1e200));
  const StepResult r = env.step(Eigen::VectorXd::Zero(1));
  EXPECT_TRUE(r.terminated);
  EXPECT_NE(r.failure.find("non-finite"), std::string::npos) << r.failure;
  EXPECT_TRUE(r.observation.allFinite());
  EXPECT_FALSE(env.render(160, 120).empty());  // drawing a broken state does not crash
}

}  // namespace
}  // namespace hlt
