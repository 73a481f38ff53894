// Cart-pole swing-up: PyBullet's InvertedPendulumSwingup rebuilt on Bullet's btMultiBody in double precision.
// A cart on a rail (prismatic x, limited to [-1, 1] m) carries a freely hinged pole; the agent pushes the
// cart with up to 100 N. theta = 0 is the pole upright; episodes start hanging down and last 1000 steps of
// 0.0165 s.
#pragma once

#include <memory>

#include "envs/bullet/robot.h"
#include "envs/bullet/world.h"
#include "envs/env.h"

namespace hlt {

class CartPoleSwingup : public Env {
 public:
  static constexpr double kDt = 0.0165;
  static constexpr double kMaxForce = 100.0;
  static constexpr double kRailLimit = 1.0;
  static constexpr int kCart = 0;  // link indices in model()
  static constexpr int kPole = 1;

  // The robot as built: cart and pole capsules with PyBullet's masses and inertias, no collisions.
  static bullet::RobotSpec model();

  CartPoleSwingup();

  std::string name() const override { return "cartpole_swingup"; }
  int observation_dim() const override { return 5; }
  int action_dim() const override { return 1; }
  int max_episode_steps() const override { return 1000; }
  double dt() const override { return kDt; }
  cv::Mat render(int width = 480, int height = 360) const override;

  // [x, x_dot, cos theta, sin theta, theta_dot].
  Eigen::VectorXd observation() const;
  bullet::Robot& robot() { return *robot_; }
  const bullet::Robot& robot() const { return *robot_; }
  bullet::World& world() { return *world_; }

 protected:
  Eigen::VectorXd reset_impl(std::mt19937_64& rng) override;
  StepResult step_impl(const Eigen::VectorXd& action) override;
  std::vector<double> save_sim() const override { return world_->save_state(); }
  void restore_sim(const std::vector<double>& sim) override { world_->restore_state(sim); }

 private:
  std::unique_ptr<bullet::World> world_;
  bullet::Robot* robot_ = nullptr;
};

}  // namespace hlt
