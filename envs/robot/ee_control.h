// End-effector velocity control: a commanded tool twist turned into joint velocities by damped least squares
// on the arm's Jacobian, with the tool kept inside a workspace box, joints kept off their limits and speeds
// within the joints' limits, behind an optional first-order low-pass filter on the command; optionally planar
// (height and orientation held).
#pragma once

#include <optional>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "envs/robot/arm.h"

namespace hlt::robot {

// qd = J^T (J J^T + damping^2 I)^-1 twist: the least-squares joint velocities, damped near singularities.
Vector7d damped_least_squares(const Jacobian& j, const Vector6d& twist, double damping);

// Scales qd down uniformly (keeping its direction) until every |qd_k| <= max_speed_k.
Vector7d limit_speeds(const Vector7d& qd, const Vector7d& max_speed);

// The linear velocity `v` cut so that `p + v h` stays inside `box`: a component that would leave it becomes
// the one that ends on the face (and one that points back in is kept).
Eigen::Vector3d clamp_to_workspace(const Eigen::Vector3d& p, const Eigen::Vector3d& v,
                                   const Eigen::AlignedBox3d& box, double h);

struct EeControlSettings {
  double damping = 0.01;
  Eigen::AlignedBox3d workspace{Eigen::Vector3d::Constant(-10), Eigen::Vector3d::Constant(10)};
  // The filter keeps `filter` of the previous command at each control step (0: no filter).
  double filter = 0.0;
  // Joints are slowed so that one sub-step never crosses their limit less this margin (rad).
  double limit_margin = 0.01;
  // Planar control: the tool's height and orientation are held here (world) by proportional corrections,
  // `hold_gain` per second, that replace what the command says about them.
  std::optional<double> hold_height;
  std::optional<Eigen::Matrix3d> hold_orientation;
  double hold_gain = 10.0;
};

class EeVelocityController {
 public:
  explicit EeVelocityController(EeControlSettings settings = {});
  const EeControlSettings& settings() const { return settings_; }

  // Takes a new command (once per control step): the filtered twist becomes filter v_f + (1 - filter) v.
  void command(const Vector6d& twist);
  const Vector6d& filtered() const { return filtered_; }
  // Joint velocities for the next sub-step of `h` seconds, from the arm's current configuration.
  Vector7d joint_velocities(const Arm& arm, double h) const;
  // Forgets the filter's past (at reset).
  void reset() { filtered_.setZero(); }

  // The filter's state, for snapshots.
  const Vector6d& state() const { return filtered_; }
  void set_state(const Vector6d& s) { filtered_ = s; }

 private:
  EeControlSettings settings_;
  Vector6d filtered_ = Vector6d::Zero();
};

}  // namespace hlt::robot
