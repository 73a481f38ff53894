#include "envs/cartpole_swingup.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "envs/bullet/draw.h"
#include "envs/render.h"

namespace hlt {

bullet::RobotSpec CartPoleSwingup::model() {
  bullet::RobotSpec spec;
  spec.name = "cartpole";
  spec.base.name = "rail";
  spec.fixed_base = true;

  bullet::LinkSpec cart;
  cart.name = "cart";
  cart.parent = -1;
  cart.joint = bullet::JointType::kPrismatic;
  cart.axis = Eigen::Vector3d::UnitX();
  cart.limits = std::make_pair(-kRailLimit, kRailLimit);
  const double cart_radius = 0.1, cart_half_length = 0.1;
  cart.mass = bullet::capsule_mass(cart_radius, 2 * cart_half_length);
  cart.inertia = bullet::capsule_inertia(cart.mass, cart_radius, cart_half_length, /*axis=*/0);
  cart.shapes = {bullet::Shape::capsule({-cart_half_length, 0, 0}, {cart_half_length, 0, 0}, cart_radius)};

  bullet::LinkSpec pole;
  pole.name = "pole";
  pole.parent = 0;
  pole.joint = bullet::JointType::kRevolute;
  pole.axis = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d from(0, 0, 0), to(0.001, 0, 0.6);
  const double pole_radius = 0.049;
  pole.mass = bullet::capsule_mass(pole_radius, (to - from).norm());
  pole.inertia = bullet::fromto_capsule_inertia(pole.mass, from, to, pole_radius);
  pole.com = 0.5 * (from + to);
  pole.shapes = {bullet::Shape::capsule(from, to, pole_radius)};

  spec.links = {cart, pole};
  return spec;
}

CartPoleSwingup::CartPoleSwingup() : world_(std::make_unique<bullet::World>()) {
  robot_ = &world_->add_robot(model());
}

Eigen::VectorXd CartPoleSwingup::observation() const {
  const double theta = robot_->joint_position(kPole);
  Eigen::VectorXd obs(5);
  obs << robot_->joint_position(kCart), robot_->joint_velocity(kCart), std::cos(theta), std::sin(theta),
      robot_->joint_velocity(kPole);
  return obs;
}

Eigen::VectorXd CartPoleSwingup::reset_impl(std::mt19937_64& rng) {
  robot_->clear_joint_forces();
  robot_->set_joint_state(kCart, 0.0, 0.0);
  robot_->set_joint_state(kPole, 3.1415 + std::uniform_real_distribution<double>(-0.1, 0.1)(rng), 0.0);
  return observation();
}

StepResult CartPoleSwingup::step_impl(const Eigen::VectorXd& action) {
  robot_->set_joint_force(kCart, kMaxForce * std::clamp(action[0], -1.0, 1.0));
  world_->step(kDt, 1);
  StepResult r;
  if (!world_->state_is_finite()) {
    r.terminated = true;
    r.failure =
        fmt::format("cartpole_swingup: the Bullet state became non-finite at step {}", elapsed_steps() + 1);
    r.observation = Eigen::VectorXd::Constant(5, std::nan(""));
    return r;
  }
  r.observation = observation();
  r.reward = r.observation[2];  // cos theta after the step
  return r;
}

cv::Mat CartPoleSwingup::render(int width, int height) const {
  // At least 3 m across (rail and cart) and 1.6 m high (the pole up and down).
  SideView view(width, height, 0.0, 0.0, std::max(3.0, 1.6 * width / std::max(1, height)));
  view.line(-kRailLimit - 0.25, 0, kRailLimit + 0.25, 0, colours::kGround, 2);
  for (double x : {-kRailLimit, kRailLimit})
    view.line(x, -0.12, x, 0.12, colours::kGround, 2);
  bullet::draw_side(view, *robot_);
  view.caption(fmt::format("t={}  x={:.2f}  theta={:.2f}", elapsed_steps(), robot_->joint_position(kCart),
                           std::remainder(robot_->joint_position(kPole), 6.283185307179586)));
  return view.image();
}

std::unique_ptr<Env> make_cartpole_swingup() {
  return std::make_unique<CartPoleSwingup>();
}

}  // namespace hlt
