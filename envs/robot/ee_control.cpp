#include "envs/robot/ee_control.h"

#include <algorithm>
#include <cmath>

#include "hlt/util/error.h"

namespace hlt::robot {

Vector7d damped_least_squares(const Jacobian& j, const Vector6d& twist, double damping) {
  const Eigen::Matrix<double, 6, 6> a =
      j * j.transpose() + damping * damping * Eigen::Matrix<double, 6, 6>::Identity();
  return j.transpose() * a.ldlt().solve(twist);
}

Vector7d limit_speeds(const Vector7d& qd, const Vector7d& max_speed) {
  double scale = 1.0;
  for (int k = 0; k < 7; ++k) {
    if (std::abs(qd[k]) > max_speed[k]) scale = std::min(scale, max_speed[k] / std::abs(qd[k]));
  }
  return qd * scale;
}

Eigen::Vector3d clamp_to_workspace(const Eigen::Vector3d& p, const Eigen::Vector3d& v,
                                   const Eigen::AlignedBox3d& box, double h) {
  Eigen::Vector3d out = v;
  for (int i = 0; i < 3; ++i) {
    const double next = p[i] + v[i] * h;
    if (next > box.max()[i] && v[i] > 0) out[i] = std::max(0.0, (box.max()[i] - p[i]) / h);
    if (next < box.min()[i] && v[i] < 0) out[i] = std::min(0.0, (box.min()[i] - p[i]) / h);
  }
  return out;
}

EeVelocityController::EeVelocityController(EeControlSettings settings) : settings_(settings) {
  check(settings_.filter >= 0 && settings_.filter < 1,
        "end-effector control: filter must be in [0, 1), got {}", settings_.filter);
  check(settings_.damping > 0, "end-effector control: damping must be positive");
}

void EeVelocityController::command(const Vector6d& twist) {
  check(twist.allFinite(), "end-effector control: command must be finite");
  filtered_ = settings_.filter * filtered_ + (1.0 - settings_.filter) * twist;
}

Vector7d EeVelocityController::joint_velocities(const Arm& arm, double h) const {
  Vector6d twist = filtered_;
  // Held degrees of freedom are corrected at every sub-step from the current pose, so contact forces and
  // tracking errors do not accumulate into drift over an episode.
  const Eigen::Isometry3d pose = arm.tool_pose();
  if (settings_.hold_height)
    twist[2] = settings_.hold_gain * (*settings_.hold_height - pose.translation().z());
  if (settings_.hold_orientation)
    twist.tail<3>() = settings_.hold_gain * orientation_error(*settings_.hold_orientation, pose.linear());
  twist.head<3>() = clamp_to_workspace(pose.translation(), twist.head<3>(), settings_.workspace, h);
  Vector7d qd = damped_least_squares(arm.jacobian(), twist, settings_.damping);
  const ArmModel& m = arm.model();
  const Vector7d q = arm.positions();
  for (int k = 0; k < 7; ++k) {
    // Stop at the limit (less the margin) rather than let the limit constraint catch the joint.
    const double hi = (m.upper[k] - settings_.limit_margin - q[k]) / h;
    const double lo = (m.lower[k] + settings_.limit_margin - q[k]) / h;
    qd[k] = std::clamp(qd[k], std::min(lo, 0.0), std::max(hi, 0.0));
  }
  return limit_speeds(qd, m.max_speed);
}

}  // namespace hlt::robot
