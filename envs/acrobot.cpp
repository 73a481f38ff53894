#include "envs/acrobot.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "envs/render.h"
#include "hlt/util/error.h"

namespace hlt {

namespace {
constexpr double kPi = 3.14159265358979323846;
}

Acrobot::State Acrobot::derivative(const State& s, double tau) {
  const double t1 = s[0], t2 = s[1], w1 = s[2], w2 = s[3];
  const double m1 = kMass1, m2 = kMass2, l1 = kLength1, lc1 = kCom1, lc2 = kCom2, g = kGravity;
  const double d1 =
      m1 * lc1 * lc1 + m2 * (l1 * l1 + lc2 * lc2 + 2 * l1 * lc2 * std::cos(t2)) + kInertia1 + kInertia2;
  const double d2 = m2 * (lc2 * lc2 + l1 * lc2 * std::cos(t2)) + kInertia2;
  const double phi2 = m2 * lc2 * g * std::cos(t1 + t2 - kPi / 2);
  const double phi1 = -m2 * l1 * lc2 * w2 * w2 * std::sin(t2) - 2 * m2 * l1 * lc2 * w2 * w1 * std::sin(t2) +
                      (m1 * lc1 + m2 * l1) * g * std::cos(t1 - kPi / 2) + phi2;
  const double a2 = (tau + d2 / d1 * phi1 - m2 * l1 * lc2 * w1 * w1 * std::sin(t2) - phi2) /
                    (m2 * lc2 * lc2 + kInertia2 - d2 * d2 / d1);
  const double a1 = -(d2 * a2 + phi1) / d1;
  return {w1, w2, a1, a2};
}

void Acrobot::set_state(const State& s) {
  check(s.allFinite(), "acrobot: state must be finite");
  state_ = s;
}

Eigen::VectorXd Acrobot::observation() const {
  Eigen::VectorXd obs(6);
  obs << std::cos(state_[0]), std::sin(state_[0]), std::cos(state_[1]), std::sin(state_[1]), state_[2],
      state_[3];
  return obs;
}

double Acrobot::tip_height() const {
  return -std::cos(state_[0]) - std::cos(state_[0] + state_[1]);
}

Eigen::VectorXd Acrobot::reset_impl(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  for (int i = 0; i < 4; ++i)
    state_[i] = u(rng);
  last_torque_ = 0.0;
  return observation();
}

StepResult Acrobot::step_impl(const Eigen::VectorXd& action) {
  const double tau = std::clamp(action[0], -kMaxTorque, kMaxTorque);
  StepResult r;
  // Scored on the state the action was taken in.
  r.reward = -(0.001 * tau * tau + std::cos(state_[0]) + std::cos(state_[0] + state_[1]));
  const State& s = state_;
  const double h = kDt;
  const State k1 = derivative(s, tau);
  const State k2 = derivative(s + 0.5 * h * k1, tau);
  const State k3 = derivative(s + 0.5 * h * k2, tau);
  const State k4 = derivative(s + h * k3, tau);
  state_ = s + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4);
  last_torque_ = tau;
  r.observation = observation();
  if (!state_.allFinite()) {
    r.terminated = true;
    r.failure = fmt::format("acrobot: the state became non-finite at step {}", elapsed_steps() + 1);
    return r;
  }
  r.terminated = tip_height() > kGoalHeight;
  return r;
}

std::vector<double> Acrobot::save_sim() const {
  return {state_[0], state_[1], state_[2], state_[3], last_torque_};
}

void Acrobot::restore_sim(const std::vector<double>& sim) {
  check(sim.size() == 5, "acrobot: snapshot has {} values, expected 5", sim.size());
  set_state(State(sim[0], sim[1], sim[2], sim[3]));
  check(std::isfinite(sim[4]), "acrobot: snapshot torque is not finite");
  last_torque_ = sim[4];
}

cv::Mat Acrobot::render(int width, int height) const {
  SideView view(width, height, 0.0, 0.0, std::max(4.6, 4.6 * width / std::max(1, height)));
  const double t1 = state_[0], t12 = state_[0] + state_[1];
  const double x1 = kLength1 * std::sin(t1), z1 = -kLength1 * std::cos(t1);
  const double x2 = x1 + std::sin(t12), z2 = z1 - std::cos(t12);
  view.line(-2.2, kGoalHeight, 2.2, kGoalHeight, colours::kGround, 1);  // the height that ends the episode
  view.capsule(0, 0, x1, z1, 0.06, colours::kBody);
  view.capsule(x1, z1, x2, z2, 0.06, colours::kLimb);
  view.disc(0, 0, 0.05, colours::kJoint);
  view.disc(x1, z1, 0.05, colours::kJoint);
  view.line(0, -2.1, 0.8 * last_torque_ / kMaxTorque, -2.1, colours::kBody, 6);  // the elbow torque
  view.caption(fmt::format("t={}  tip height={:.2f}", elapsed_steps(), tip_height()));
  return view.image();
}

std::unique_ptr<Env> make_acrobot() {
  return std::make_unique<Acrobot>();
}

}  // namespace hlt
