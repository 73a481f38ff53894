// Tabletop: the robot scenes' simulation — a table, one arm standing at its edge, boxes (blocks) with
// friction on it, stepped in control steps of several Bullet sub-steps with the end-effector velocity
// controller in the loop, with exact snapshots and a side and top view.
//
// World frame: the table top is z = 0 and the arm's base frame sits at the origin on it, so positions are in
// the robot's base frame as the paper's workspace numbers are. Only the tool, fingers, blocks and table
// collide; blocks and table have world-sized bounding boxes, so Bullet's set of contact pairs is fixed when
// the scene is built, which is what makes snapshots exact (see bullet::World::save_state).
#pragma once

#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "envs/bullet/world.h"
#include "envs/robot/arm.h"
#include "envs/robot/ee_control.h"

namespace hlt::robot {

// The tool pointing straight down at the table (x along the table's x, z down): the orientation both tasks
// start in and hold.
inline Eigen::Matrix3d tool_down() {
  return Eigen::Vector3d(1, -1, -1).asDiagonal();
}

enum class ArmKind { kSawyer, kPanda };

struct BlockSpec {
  Eigen::Vector3d half_extents = Eigen::Vector3d::Constant(0.025);
  double mass = 0.1;
  double friction = 0.5;
  cv::Scalar colour{40, 40, 200};  // BGR
};

struct TabletopSettings {
  ArmKind arm = ArmKind::kSawyer;
  std::vector<BlockSpec> blocks = {BlockSpec{}};
  double table_friction = 0.5;
  // The table top's extent in x and y (m). By default the Panda stands on it and the Sawyer's pedestal at its
  // near edge.
  std::optional<Eigen::AlignedBox2d> table;
  double control_dt = 0.1;
  int substeps = 24;  // Bullet steps of control_dt / substeps (240 Hz at 10 Hz control)
  int solver_iterations = 50;
  EeControlSettings control;
};

class Tabletop {
 public:
  explicit Tabletop(const TabletopSettings& settings);
  ~Tabletop();
  Tabletop(const Tabletop&) = delete;
  Tabletop& operator=(const Tabletop&) = delete;

  const TabletopSettings& settings() const { return settings_; }
  Arm& arm() { return *arm_; }
  const Arm& arm() const { return *arm_; }
  bullet::World& world() { return *world_; }
  EeVelocityController& controller() { return controller_; }
  int num_blocks() const { return static_cast<int>(blocks_.size()); }

  Eigen::Isometry3d block_pose(int i) const;
  Eigen::Vector3d block_velocity(int i) const;
  // Puts block `i` at rest at `position` turned by `yaw` about z.
  void set_block(int i, const Eigen::Vector3d& position, double yaw);
  // The arm at rest at `q` with its fingers `finger_opening` open, the filter emptied, every contact
  // forgotten, the wrist wrench the resting one.
  void reset_arm(const Vector7d& q, double finger_opening = 0.0);

  // One control step: the controller takes `twist` (tool velocity, world: linear then angular) and the
  // fingers `finger_speed` (m/s, + opens); then `substeps` sub-steps, each with fresh joint velocities.
  void step(const Vector6d& twist, double finger_speed = 0.0);
  // The wrist wrench averaged over the last control step's sub-steps (force, torque; see Arm::wrist_wrench).
  const Vector6d& wrist_wrench() const { return mean_wrench_; }
  // The force (N, world) that something other than the arm exerts on the hand, averaged over the last control
  // step: the wrist force less the hand's weight, corrected by the hand's m a (its momentum's change over the
  // step), so that it reads zero for a hand at rest or moving freely. A real arm reports this estimate (the
  // Panda's external wrench is computed from its dynamic model); the raw wrist force also carries m a of the
  // hand, which follows the commanded velocity's changes rather than contacts (about 1 N at the expert's
  // speed changes).
  const Eigen::Vector3d& external_force() const { return external_force_; }

  std::vector<double> save_state() const;
  // Throws hlt::Error for a snapshot of the wrong size or with NaN/Inf values.
  void restore_state(const std::vector<double>& state);
  bool state_is_finite() const;

  // The side view (x right, z up) beside the top view (x right, y up). `marks` are extra points drawn as
  // rings in the top view (a target).
  cv::Mat render(int width, int height, const std::vector<Eigen::Vector3d>& marks = {}) const;

 private:
  TabletopSettings settings_;
  std::unique_ptr<bullet::World> world_;
  std::unique_ptr<Arm> arm_;
  Eigen::AlignedBox2d table_;
  std::vector<bullet::Robot*> blocks_;
  EeVelocityController controller_;
  double finger_speed_ = 0.0;
  double gravity_z_ = 0.0;
  Vector6d mean_wrench_ = Vector6d::Zero();
  Eigen::Vector3d external_force_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d hand_momentum_ = Eigen::Vector3d::Zero();  // at the end of the last step
};

// The yaw (rotation about world z) of a pose's x axis.
double yaw_of(const Eigen::Isometry3d& pose);

}  // namespace hlt::robot
