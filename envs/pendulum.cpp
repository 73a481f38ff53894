#include "envs/pendulum.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "envs/render.h"
#include "hlt/util/error.h"

namespace hlt {

namespace {
constexpr double kPi = 3.14159265358979323846;

// gym's angle_normalize: Python's floored modulo puts the result in [-pi, pi).
double wrap_angle(double x) {
  double m = std::fmod(x + kPi, 2 * kPi);
  if (m < 0) m += 2 * kPi;
  return m - kPi;
}
}  // namespace

void Pendulum::set_state(double theta, double theta_dot) {
  check(std::isfinite(theta) && std::isfinite(theta_dot), "pendulum: state must be finite");
  theta_ = theta;
  theta_dot_ = theta_dot;
}

Eigen::VectorXd Pendulum::observation() const {
  Eigen::VectorXd obs(3);
  obs << std::cos(theta_), std::sin(theta_), theta_dot_;
  return obs;
}

Eigen::VectorXd Pendulum::reset_impl(std::mt19937_64& rng) {
  theta_ = std::uniform_real_distribution<double>(-kPi, kPi)(rng);
  theta_dot_ = std::uniform_real_distribution<double>(-1.0, 1.0)(rng);
  last_torque_ = 0.0;
  return observation();
}

StepResult Pendulum::step_impl(const Eigen::VectorXd& action) {
  const double u = std::clamp(kMaxTorque * action[0], -kMaxTorque, kMaxTorque);
  StepResult r;
  // The reward scores the state the action was taken in, as gym does.
  const double th = wrap_angle(theta_);
  r.reward = -(th * th + 0.1 * theta_dot_ * theta_dot_ + 0.001 * u * u);
  double new_theta_dot = theta_dot_ + (-3.0 * kGravity / (2.0 * kLength) * std::sin(theta_ + kPi) +
                                       3.0 / (kMass * kLength * kLength) * u) *
                                          kDt;
  // The position update uses the speed before clipping (gym's order).
  theta_ = theta_ + new_theta_dot * kDt;
  theta_dot_ = std::clamp(new_theta_dot, -kMaxSpeed, kMaxSpeed);
  last_torque_ = u;
  r.observation = observation();
  return r;
}

void Pendulum::restore_sim(const std::vector<double>& sim) {
  check(sim.size() == 3, "pendulum: snapshot has {} values, expected 3", sim.size());
  set_state(sim[0], sim[1]);
  last_torque_ = sim[2];
}

cv::Mat Pendulum::render(int width, int height) const {
  SideView view(width, height, 0.0, 0.0, 2.8 * width / std::max(1, std::min(width, height)));
  // theta grows counter-clockwise from upright, as in gym's drawing.
  const double tip_x = -kLength * std::sin(theta_), tip_z = kLength * std::cos(theta_);
  view.capsule(0, 0, tip_x, tip_z, 0.06, colours::kLimb);
  view.disc(0, 0, 0.05, colours::kJoint);
  // The applied torque as a bar along the bottom edge: right for positive (counter-clockwise) torque.
  const double bar_z = -1.2;
  view.line(0, bar_z, 0.5 * last_torque_ / kMaxTorque, bar_z, colours::kBody, 6);
  view.caption(fmt::format("t={}  theta={:.2f}", elapsed_steps(), wrap_angle(theta_)));
  return view.image();
}

std::unique_ptr<Env> make_pendulum() {
  return std::make_unique<Pendulum>();
}

}  // namespace hlt
