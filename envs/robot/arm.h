// Arm: a 7-joint robot arm in a Bullet world, built in code from published kinematic numbers (a Sawyer-like
// arm with a pushing tool, a Panda-like arm with a two-finger gripper), with what a real arm's low-level
// controller gives: a velocity motor per joint bounded by the joint's effort, speed limits, the tool's pose
// and Jacobian, and the wrench at the wrist from Bullet's joint feedback.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "envs/bullet/robot.h"
#include "envs/bullet/world.h"

class btMultiBodyJointMotor;
struct btMultiBodyJointFeedback;

namespace hlt::robot {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Vector7d = Eigen::Matrix<double, 7, 1>;
// Tool velocity per joint velocity: rows 0-2 the linear velocity of the tool centre point, rows 3-5 the
// angular velocity, both in world coordinates.
using Jacobian = Eigen::Matrix<double, 6, 7>;

// Everything that makes up one arm: the multibody (as RobotSpec data) and what the controller needs to know.
struct ArmModel {
  std::string name;
  bullet::RobotSpec spec;
  std::array<int, 7> joints{};  // the arm joints' links in spec.links, base to wrist
  Vector7d lower = Vector7d::Zero(), upper = Vector7d::Zero();  // joint position limits (rad)
  Vector7d max_speed = Vector7d::Zero();                        // rad/s
  Vector7d max_effort = Vector7d::Zero();                       // N m
  int hand = -1;  // the link fixed to the flange; its joint carries the wrist sensor
  // The tool centre point and the tool frame (z: the approach direction) in the hand's body frame.
  Eigen::Isometry3d tool_in_hand = Eigen::Isometry3d::Identity();
  std::vector<int> fingers;  // prismatic finger links, each opening from 0 to finger_travel
  double finger_travel = 0.0, finger_max_speed = 0.0, finger_max_force = 0.0;
  // A configuration with the tool pointing down over the table, where inverse kinematics starts.
  Vector7d seed = Vector7d::Zero();
};

// The Sawyer from Rethink's published URDF joint origins (ROBOT_TASKS.md), mounted with its base frame at
// `base`; a 0.12 m pushing rod with a 15 mm tip as the tool.
ArmModel sawyer_model(const Eigen::Vector3d& base);
// The Panda from Franka's published (Craig) DH parameters, base at `base`, with the hand and two fingers.
ArmModel panda_model(const Eigen::Vector3d& base);

class Arm {
 public:
  // Builds the arm in `world`; the world must outlive it.
  Arm(bullet::World& world, ArmModel model);
  ~Arm();
  Arm(const Arm&) = delete;
  Arm& operator=(const Arm&) = delete;

  const ArmModel& model() const { return model_; }
  const bullet::Robot& robot() const { return *robot_; }

  Vector7d positions() const;
  Vector7d velocities() const;
  // Sets the arm joints (at rest) and opens the fingers to `finger_opening` each.
  void set_configuration(const Vector7d& q, double finger_opening = 0.0);
  double finger_opening() const;  // the mean of the fingers' openings (m); 0 without fingers

  // Forward kinematics of the current configuration.
  Eigen::Isometry3d tool_pose() const;
  // The geometric Jacobian at the tool centre point, from Bullet's constraint Jacobian of the hand link.
  Jacobian jacobian() const;
  Vector6d tool_twist() const { return jacobian() * velocities(); }

  // For the next sub-step of `h` seconds: each arm joint's motor drives towards qd (clipped to the speed
  // limits) with at most its effort, the finger motors towards `finger_speed` (m/s, + opens). No joint
  // torques besides the motors' act: Bullet's joint feedback counts joint torques once more in its constraint
  // pass (without gravity there), so a gravity-compensating torque would show at the wrist as a second
  // weight.
  void drive(const Vector7d& qd, double finger_speed, double h);

  // The force (N) and torque (N m, about the hand's centre of mass) the hand and everything on it exert on
  // the flange during the last sub-step, world coordinates: holding a block adds its weight, (0, 0, -m g), to
  // the force.
  Vector6d wrist_wrench() const;
  // The mass (kg) of what hangs on the flange's joint with nothing held: the hand and its fingers.
  double hand_mass() const;
  // wrist_wrench() with the arm at rest and nothing touching the hand, under gravity (0, 0, gravity_z): the
  // hand's weight, no torque (the fingers sit symmetrically about the hand's centre of mass).
  Vector6d resting_wrist_wrench(double gravity_z) const;
  // The linear momentum (kg m/s, world) of the hand and its fingers: its rate of change is the force the
  // wrist spends accelerating them.
  Eigen::Vector3d hand_momentum() const;

  // Damped least-squares inverse kinematics of the tool pose from `start` (positions and orientation), within
  // the joint limits. Returns whether it converged to 0.1 mm and 1 mrad; leaves the arm at the result.
  bool solve_ik(const Eigen::Isometry3d& target, const Vector7d& start, Vector7d* q);

 private:
  ArmModel model_;
  bullet::Robot* robot_;
  std::vector<std::unique_ptr<btMultiBodyJointMotor>> motors_;  // the 7 joints, then the fingers
  std::unique_ptr<btMultiBodyJointFeedback> feedback_;
  btMultiBodyDynamicsWorld& world_;
  int dofs_;  // the multibody's degrees of freedom (arm and fingers)
  int dof(int link) const;
  // Row `normal_lin . v + normal_ang . w` of `link` at `point`: the multibody's own joint velocities.
  Eigen::VectorXd jacobian_row(int link, const Eigen::Vector3d& point, const Eigen::Vector3d& normal_ang,
                               const Eigen::Vector3d& normal_lin) const;
};

// The rotation vector taking `from` to `to` (world): log(to from^T).
Eigen::Vector3d orientation_error(const Eigen::Matrix3d& to, const Eigen::Matrix3d& from);

}  // namespace hlt::robot
