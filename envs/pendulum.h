// Pendulum swing-up with gym Pendulum-v0 dynamics (analytic, semi-implicit Euler, dt 0.05): a unit rod
// under gravity g = 10 with a torque of at most 2 N m (the agent's action times 2). theta = 0 is upright.
#pragma once

#include "envs/env.h"

namespace hlt {

class Pendulum : public Env {
 public:
  static constexpr double kGravity = 10.0;
  static constexpr double kMass = 1.0;
  static constexpr double kLength = 1.0;
  static constexpr double kDt = 0.05;
  static constexpr double kMaxSpeed = 8.0;
  static constexpr double kMaxTorque = 2.0;

  std::string name() const override { return "pendulum"; }
  int observation_dim() const override { return 3; }
  int action_dim() const override { return 1; }
  int max_episode_steps() const override { return 200; }
  double dt() const override { return kDt; }
  cv::Mat render(int width = 480, int height = 360) const override;

  double theta() const { return theta_; }
  double theta_dot() const { return theta_dot_; }
  // Puts the pendulum in a given state (for tests and analysis; reset() still starts an episode).
  void set_state(double theta, double theta_dot);
  // [cos theta, sin theta, theta_dot].
  Eigen::VectorXd observation() const;

 protected:
  Eigen::VectorXd reset_impl(std::mt19937_64& rng) override;
  StepResult step_impl(const Eigen::VectorXd& action) override;
  std::vector<double> save_sim() const override { return {theta_, theta_dot_, last_torque_}; }
  void restore_sim(const std::vector<double>& sim) override;

 private:
  double theta_ = 0.0;
  double theta_dot_ = 0.0;
  double last_torque_ = 0.0;  // only drawn by render()
};

}  // namespace hlt
