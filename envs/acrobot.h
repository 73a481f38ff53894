// Continuous acrobot swing-up: the classic two-link acrobot (unit masses and lengths, COMs at mid-length,
// unit link inertias, g = 9.8) with a continuous elbow torque in [-1, 1] N m, integrated with one RK4 step of
// 0.2 s per environment step. theta1 = 0 hangs down; the episode ends when the tip rises 1.5 m above the
// pivot, or after 500 steps.
#pragma once

#include <Eigen/Core>

#include "envs/env.h"

namespace hlt {

class Acrobot : public Env {
 public:
  static constexpr double kDt = 0.2;
  static constexpr double kMass1 = 1.0, kMass2 = 1.0;
  static constexpr double kLength1 = 1.0;
  static constexpr double kCom1 = 0.5, kCom2 = 0.5;
  static constexpr double kInertia1 = 1.0, kInertia2 = 1.0;  // about the link's COM
  static constexpr double kGravity = 9.8;
  static constexpr double kMaxTorque = 1.0;
  static constexpr double kGoalHeight = 1.5;

  // The state is [theta1, theta2, theta1_dot, theta2_dot].
  using State = Eigen::Vector4d;
  // d(state)/dt under elbow torque `tau` (the classic "book" equations of motion).
  static State derivative(const State& s, double tau);

  std::string name() const override { return "acrobot"; }
  int observation_dim() const override { return 6; }
  int action_dim() const override { return 1; }
  int max_episode_steps() const override { return 500; }
  double dt() const override { return kDt; }
  cv::Mat render(int width = 480, int height = 360) const override;

  const State& state() const { return state_; }
  void set_state(const State& s);
  // [cos t1, sin t1, cos t2, sin t2, t1_dot, t2_dot].
  Eigen::VectorXd observation() const;
  // Height of the tip above the pivot: -cos t1 - cos(t1 + t2).
  double tip_height() const;

 protected:
  Eigen::VectorXd reset_impl(std::mt19937_64& rng) override;
  StepResult step_impl(const Eigen::VectorXd& action) override;
  std::vector<double> save_sim() const override;
  void restore_sim(const std::vector<double>& sim) override;

 private:
  State state_ = State::Zero();
  double last_torque_ = 0.0;  // only drawn by render()
};

}  // namespace hlt
