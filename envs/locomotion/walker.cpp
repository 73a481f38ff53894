#include "envs/locomotion/walker.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/core.hpp>

#include "envs/bullet/draw.h"
#include "envs/render.h"
#include "hlt/util/error.h"

namespace hlt::locomotion {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Roll, pitch and yaw of a rotation R = Rz(yaw) Ry(pitch) Rx(roll), with pitch in [-pi/2, pi/2], as
// PyBullet's getEulerFromQuaternion reports them: within 1e-5 of the gimbal lock roll is set to 0 and the
// whole turn about z goes to yaw.
Eigen::Vector3d roll_pitch_yaw(const Eigen::Quaterniond& q) {
  const double w = q.w(), x = q.x(), y = q.y(), z = q.z();
  const double s = -2.0 * (x * z - w * y);
  if (s <= -0.99999) return {0.0, -0.5 * kPi, 2.0 * std::atan2(x, -y)};
  if (s >= 0.99999) return {0.0, 0.5 * kPi, 2.0 * std::atan2(-x, y)};
  return {std::atan2(2.0 * (y * z + w * x), w * w - x * x - y * y + z * z), std::asin(s),
          std::atan2(2.0 * (x * y + w * z), w * w + x * x - y * y - z * z)};
}

}  // namespace

Walker::Walker(WalkerSpec spec) : spec_(std::move(spec)), model_(build(spec_.model)) {
  check(spec_.power > 0 && std::isfinite(spec_.power), "walker '{}': power must be positive, got {}",
        spec_.name, spec_.power);
  check(!model_.joints.empty(), "walker '{}': the robot has no actuated joints", spec_.name);
  world_ = std::make_unique<bullet::World>();
  // The floor comes first, as PyBullet loads the stadium before the robot (this fixes the order of Bullet's
  // contact pairs).
  world_->add_ground(spec_.ground_friction, spec_.ground_restitution);
  robot_ = &world_->add_robot(model_.spec);
  torso_ = model_.link_of(spec_.torso);
  for (const std::string& f : spec_.feet)
    feet_.push_back(model_.link_of(f));
  for (int i : spec_.alive.forbidden_feet)
    check(i >= 0 && i < static_cast<int>(feet_.size()), "walker '{}': alive rule names foot {} of {}",
          spec_.name, i, feet_.size());
  start_state_ = robot_->save_state();
  // Views a little more than twice the robot's size across.
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (int link = -1; link < robot_->num_links(); ++link) {
    for (const bullet::Shape& s : robot_->world_shapes(link)) {
      lo = lo.cwiseMin((s.from.cwiseMin(s.to).array() - s.radius).matrix());
      hi = hi.cwiseMax((s.from.cwiseMax(s.to).array() + s.radius).matrix());
    }
  }
  view_size_ = std::clamp(2.2 * (hi - lo).maxCoeff(), 2.5, 10.0);
  feet_contact_.assign(feet_.size(), 0.0);
  joint_speeds_ = Eigen::VectorXd::Zero(action_dim());
}

Eigen::Vector2d Walker::parts_mean() const {
  // PyBullet's parts: every link (the massless joint links too) and the base when it floats, at their COMs,
  // plus the floor at the origin.
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  int count = 1;
  if (!model_.spec.fixed_base) {
    sum += robot_->com_position(-1).head<2>();
    ++count;
  }
  for (int i = 0; i < robot_->num_links(); ++i) {
    sum += robot_->com_position(i).head<2>();
    ++count;
  }
  return sum / count;
}

Eigen::VectorXd Walker::observe() {
  const int n = action_dim();
  Eigen::VectorXd obs(observation_dim());
  at_limit_ = 0;
  for (int i = 0; i < n; ++i) {
    const ActuatedJoint& j = model_.joints[i];
    const double mid = 0.5 * (j.lower + j.upper);
    const double q = 2.0 * (robot_->joint_position(j.link) - mid) / (j.upper - j.lower);
    joint_speeds_[i] = 0.1 * robot_->joint_velocity(j.link);
    obs[8 + 2 * i] = q;
    obs[9 + 2 * i] = joint_speeds_[i];
    if (std::abs(q) > 0.99) ++at_limit_;
  }

  const Eigen::Vector2d mean = parts_mean();
  const double dx = kTargetX - mean.x(), dy = kTargetY - mean.y();
  const Eigen::Vector3d rpy = roll_pitch_yaw(robot_->com_orientation(torso_));
  const double yaw = rpy.z();
  z_ = robot_->com_position(torso_).z();
  pitch_ = rpy.y();
  const double angle_to_target = std::atan2(dy, dx) - yaw;
  // The torso's velocity seen from its heading.
  const Eigen::Vector3d v = robot_->com_linear_velocity(torso_);
  const double c = std::cos(-yaw), s = std::sin(-yaw);
  obs.head<8>() << z_ - initial_z_, std::sin(angle_to_target), std::cos(angle_to_target),
      0.3 * (c * v.x() - s * v.y()), 0.3 * (s * v.x() + c * v.y()), 0.3 * v.z(), rpy.x(), rpy.y();
  for (size_t f = 0; f < feet_.size(); ++f)
    obs[8 + 2 * n + f] = feet_contact_[f];

  potential_next_ = -std::sqrt(dy * dy + dx * dx) / kDt;
  return obs.cwiseMax(-5.0).cwiseMin(5.0);
}

void Walker::refresh_feet_contact() {
  for (size_t f = 0; f < feet_.size(); ++f)
    feet_contact_[f] = world_->touches_ground(*robot_, feet_[f]) ? 1.0 : 0.0;
}

void Walker::set_next_start(const Eigen::VectorXd& q) {
  check(q.size() == action_dim() && q.allFinite(), "{}: a start needs {} finite joint angles, got {}",
        spec_.name, action_dim(), q.size());
  next_start_ = q;
}

Eigen::VectorXd Walker::reset_impl(std::mt19937_64& rng) {
  robot_->restore_state(start_state_.data(), start_state_.size());
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  for (int i = 0; i < action_dim(); ++i) {
    const double drawn = u(rng);
    robot_->set_joint_state(model_.joints[i].link, next_start_ ? (*next_start_)[i] : drawn, 0.0);
  }
  next_start_.reset();
  // PyBullet carries contact points over from the previous episode; starting without any makes an episode
  // depend on its seed only.
  world_->clear_contacts();
  std::fill(feet_contact_.begin(), feet_contact_.end(), 0.0);
  initial_z_ = robot_->com_position(torso_).z();
  const Eigen::VectorXd obs = observe();
  potential_ = potential_next_;
  terms_ = Terms();
  return obs;
}

StepResult Walker::step_impl(const Eigen::VectorXd& action) {
  for (int i = 0; i < action_dim(); ++i) {
    const ActuatedJoint& j = model_.joints[i];
    robot_->set_joint_force(j.link, spec_.power * j.power_coef * std::clamp(action[i], -1.0, 1.0));
  }
  world_->step(kDt, kSubsteps);
  StepResult r;
  if (!world_->state_is_finite()) {
    r.terminated = true;
    r.failure =
        fmt::format("{}: the Bullet state became non-finite at step {}", spec_.name, elapsed_steps() + 1);
    r.observation = Eigen::VectorXd::Constant(observation_dim(), std::nan(""));
    return r;
  }
  r.observation = observe();

  // Alive and progress use the contacts of the previous step; the contacts are refreshed afterwards, as in
  // PyBullet's step().
  bool alive = true;
  if (spec_.alive.min_z) alive = alive && z_ > *spec_.alive.min_z;
  if (spec_.alive.max_abs_pitch) alive = alive && std::abs(pitch_) < *spec_.alive.max_abs_pitch;
  for (int f : spec_.alive.forbidden_feet)
    alive = alive && feet_contact_[f] == 0.0;
  terms_ = Terms();
  terms_.alive = alive ? 1.0 : -1.0;
  r.terminated = spec_.ends_when_not_alive && !alive;
  terms_.progress = potential_next_ - potential_;
  potential_ = potential_next_;
  refresh_feet_contact();

  // The raw action (not clipped) enters the costs.
  const Eigen::ArrayXd a = action.array();
  terms_.electricity =
      kElectricityCost * (a * joint_speeds_.array()).abs().mean() + kStallTorqueCost * a.square().mean();
  terms_.joints_at_limit_count = at_limit_;
  terms_.joints_at_limit = kJointsAtLimitCost * at_limit_;
  r.reward = terms_.sum();
  return r;
}

std::vector<double> Walker::save_sim() const {
  std::vector<double> s = {potential_, initial_z_};
  s.insert(s.end(), feet_contact_.begin(), feet_contact_.end());
  const std::vector<double> w = world_->save_state();
  s.insert(s.end(), w.begin(), w.end());
  return s;
}

void Walker::restore_sim(const std::vector<double>& sim) {
  const size_t head = 2 + feet_.size();
  check(sim.size() > head, "{}: snapshot has {} values, too few for this environment", spec_.name,
        sim.size());
  check(std::all_of(sim.begin(), sim.begin() + head, [](double x) { return std::isfinite(x); }),
        "{}: snapshot contains NaN or Inf", spec_.name);
  for (size_t f = 0; f < feet_.size(); ++f)
    check(sim[2 + f] == 0.0 || sim[2 + f] == 1.0, "{}: snapshot has a foot contact of {}", spec_.name,
          sim[2 + f]);
  world_->restore_state(std::vector<double>(sim.begin() + head, sim.end()));
  potential_ = sim[0];
  initial_z_ = sim[1];
  std::copy(sim.begin() + 2, sim.begin() + head, feet_contact_.begin());
}

cv::Mat Walker::render(int width, int height) const {
  check(width > 0 && height > 0, "render size must be positive, got {}x{}", width, height);
  const Eigen::Vector3d torso = robot_->body_pose(torso_).translation();
  const auto side = [&](int w, int h) {
    const double across = view_size_;
    const double tall = across * h / w;
    // The ground sits an eighth of the way up; the view follows the torso along x.
    SideView view(w, h, torso.x(), tall * (0.5 - 0.125), across);
    const double left = torso.x() - across, right = torso.x() + across;
    view.rectangle(left, 0.0, right, -tall, colours::kGroundFill);
    view.line(left, 0.0, right, 0.0, colours::kGround, 2);
    for (double x = std::floor(left * 2) / 2; x < right; x += 0.5)
      view.line(x, 0.0, x, -0.04 * tall, colours::kGround, 1);
    bullet::draw_side(view, *robot_);
    view.caption(fmt::format("{}  t={}  x={:.2f}", spec_.name, elapsed_steps(), torso.x()));
    return view.image();
  };
  if (!spec_.top_view || width < 2) return side(width, height);
  const int left_w = width / 2;
  const cv::Mat left = side(left_w, height);
  // Seen from above: x to the right, y up, centred on the torso, a 1 m grid on the floor.
  const int w = width - left_w;
  SideView top(w, height, torso.x(), torso.y(), view_size_);
  const double half_x = view_size_, half_y = view_size_ * height / w;
  for (double x = std::floor(torso.x() - half_x); x < torso.x() + half_x; x += 1.0)
    top.line(x, torso.y() - half_y, x, torso.y() + half_y, colours::kGroundFill, 1);
  for (double y = std::floor(torso.y() - half_y); y < torso.y() + half_y; y += 1.0)
    top.line(torso.x() - half_x, y, torso.x() + half_x, y, colours::kGroundFill, 1);
  bullet::draw_top(top, *robot_);
  top.caption(fmt::format("top  y={:.2f}", torso.y()));
  cv::Mat out;
  cv::hconcat(left, top.image(), out);
  return out;
}

}  // namespace hlt::locomotion
