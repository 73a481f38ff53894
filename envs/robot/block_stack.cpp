#include "envs/robot/block_stack.h"

#include <algorithm>
#include <cmath>

#include "hlt/util/error.h"

namespace hlt::robot {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kBlockYawJitter = 0.05;
// The scene's block indices (the observation's offsets are BlockStack::kBlock and kBase).
constexpr int kTopBlock = 0, kBaseBlock = 1;

TabletopSettings stack_settings() {
  TabletopSettings s;
  s.arm = ArmKind::kPanda;
  BlockSpec block;
  block.half_extents = Eigen::Vector3d::Constant(BlockStack::kBlockHalf);
  block.mass = 0.1;
  block.friction = 0.5;
  BlockSpec base = block;
  base.colour = cv::Scalar(190, 110, 40);
  s.blocks = {block, base};
  EeControlSettings& c = s.control;
  // No low-pass filter: the commanded velocity is then the only controller state, and it is the action.
  c.filter = 0.0;
  c.workspace = Eigen::AlignedBox3d(Eigen::Vector3d(BlockStack::kXMin, BlockStack::kYMin, BlockStack::kZMin),
                                    Eigen::Vector3d(BlockStack::kXMax, BlockStack::kYMax, BlockStack::kZMax));
  c.hold_orientation = tool_down();
  return s;
}

}  // namespace

BlockStack::BlockStack() : scene_(std::make_unique<Tabletop>(stack_settings())) {
  Arm& arm = scene_->arm();
  const ArmModel& m = arm.model();
  check(std::abs(m.finger_travel - kFingerTravel) < 1e-12,
        "block_stack: expected {} m of finger travel, got {}", kFingerTravel, m.finger_travel);
  Eigen::Isometry3d start = Eigen::Isometry3d::Identity();
  start.linear() = tool_down();
  start.translation() = Eigen::Vector3d(kBlockX, kBlockY, kStartHeight);
  check(arm.solve_ik(start, m.seed, &home_), "block_stack: no joint configuration reaches the start");
  // grasped() reads the observation alone, so it assumes the fingers close along the world's y.
  const Eigen::Vector3d finger_axis =
      arm.robot().body_pose(m.fingers[0]).translation() - arm.robot().body_pose(m.fingers[1]).translation();
  check(std::abs(finger_axis.normalized().y()) > 0.999, "block_stack: the fingers do not close along y");
  place({kBlockX, kBlockY, 0.0}, {kBaseX, kBaseY, 0.0});
}

void BlockStack::place(const Eigen::Vector3d& block, const Eigen::Vector3d& base) {
  scene_->reset_arm(home_, kFingerTravel);
  scene_->set_block(kTopBlock, {block.x(), block.y(), kBlockHalf}, block.z());
  scene_->set_block(kBaseBlock, {base.x(), base.y(), kBlockHalf}, base.z());
}

Eigen::VectorXd BlockStack::reset_impl(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> jitter(-kJitter, kJitter),
      yaw_jitter(-kBlockYawJitter, kBlockYawJitter);
  // A cube's yaw matters modulo a quarter turn.
  std::uniform_real_distribution<double> byaw(-0.25 * kPi, 0.25 * kPi);
  const Eigen::Vector3d block(kBlockX + jitter(rng), kBlockY + jitter(rng), yaw_jitter(rng));
  const Eigen::Vector3d base(kBaseX + jitter(rng), kBaseY + jitter(rng), byaw(rng));
  place(block, base);
  return observation();
}

std::optional<ObservationScale> BlockStack::observation_scale() const {
  ObservationScale s;
  s.offset = Eigen::VectorXd::Zero(kObsDim);
  s.scale = Eigen::VectorXd::Ones(kObsDim);
  // The tool over the task's few centimetres in x and z, the 20 cm between the blocks' spots in y. The block
  // relative to the tool, over the centimetre that decides a grasp (from 9.5 cm under the tool at the start
  // to level with it); the base relative to the block, the way still to carry it (0.2 m in y at the start).
  // Absolute, a 1 cm offset between block and tool was a difference of 0.1-0.2 between two inputs spread
  // over the workspace, and cloned policies descended without centring over the block.
  s.reference = Eigen::VectorXi::Constant(kObsDim, -1);
  const Eigen::Vector3d centre(0.5 * (kBlockX + kBaseX), 0.5 * (kBlockY + kBaseY), 0.0);
  s.offset.segment<3>(kEe) = centre + Eigen::Vector3d(0, 0, 0.07);
  s.scale.segment<3>(kEe) = Eigen::Vector3d(0.05, 0.1, 0.03);
  s.reference.segment<3>(kBlock) = Eigen::Vector3i(kEe, kEe + 1, kEe + 2);
  s.offset.segment<3>(kBlock) = Eigen::Vector3d(0, 0, -0.05);
  s.scale.segment<3>(kBlock) = Eigen::Vector3d(0.01, 0.01, 0.03);
  s.reference.segment<3>(kBase) = Eigen::Vector3i(kBlock, kBlock + 1, kBlock + 2);
  s.offset.segment<3>(kBase) = Eigen::Vector3d(0.025, 0.1, -0.025);
  s.scale.segment<3>(kBase) = Eigen::Vector3d(0.02, 0.05, 0.02);
  s.offset[kGripper] = 0.9;
  s.scale[kGripper] = 0.1;
  s.scale.segment<3>(kForce).setConstant(2.0);
  s.scale.segment<3>(kTorque).setConstant(0.1);
  return s;
}

Eigen::Vector3d BlockStack::external_force() const {
  return scene_->external_force();
}

Eigen::VectorXd BlockStack::observation() const {
  Eigen::VectorXd o(kObsDim);
  o.segment<3>(kEe) = scene_->arm().tool_pose().translation();
  o.segment<3>(kBlock) = scene_->block_pose(kTopBlock).translation();
  o.segment<3>(kBase) = scene_->block_pose(kBaseBlock).translation();
  o[kGripper] = scene_->arm().finger_opening() / kFingerTravel;
  o.segment<3>(kForce) = external_force();
  o.segment<3>(kTorque) = scene_->wrist_wrench().tail<3>();
  return o;
}

bool BlockStack::grasped(const Eigen::VectorXd& o) {
  check(o.size() == kObsDim, "block_stack: observation has {} values, expected {}", o.size(), kObsDim);
  const double opening = o[kGripper] * kFingerTravel;
  const Eigen::Vector3d rel = o.segment<3>(kBlock) - o.segment<3>(kEe);
  // The pads (2 cm wide along x, from 5 mm below the tool centre point to the hand 4.4 cm above it) touch
  // both faces: closed to the half width less what 70 N presses into the contact, not much wider.
  return opening > kBlockHalf - 0.006 && opening < kBlockHalf + 0.003 && std::abs(rel.x()) < 0.02 &&
         std::abs(rel.y()) < 0.015 && rel.z() > -0.025 && rel.z() < 0.02;
}

Eigen::Vector3d BlockStack::stack_point(const Eigen::VectorXd& o) {
  return o.segment<3>(kBase) + Eigen::Vector3d(0, 0, 2 * kBlockHalf);
}

double BlockStack::stage_reward(const Eigen::VectorXd& o) {
  const Eigen::Vector3d ee = o.segment<3>(kEe), block = o.segment<3>(kBlock), stack = stack_point(o);
  if (grasped(o)) return -kCarryWeight * (ee - stack).norm();
  return -(ee - block).norm() - kCarryWeight * (block - stack).norm();
}

double BlockStack::reward(const Eigen::VectorXd& o, const Eigen::Vector4d& a) {
  return stage_reward(o) - kWrenchCost * (o.segment<3>(kForce).norm() + a.norm());
}

bool BlockStack::success() const {
  const Eigen::Vector3d block = scene_->block_pose(kTopBlock).translation();
  const Eigen::Vector3d base = scene_->block_pose(kBaseBlock).translation();
  return (block.head<2>() - base.head<2>()).norm() < kPlaceXY &&
         std::abs(block.z() - base.z() - 2 * kBlockHalf) < kPlaceZ &&
         scene_->block_velocity(kTopBlock).norm() < 0.01 && scene_->arm().finger_opening() > kReleasedOpening;
}

StepResult BlockStack::step_impl(const Eigen::VectorXd& action) {
  const Eigen::Vector4d a = action.cwiseMax(-1.0).cwiseMin(1.0);
  Vector6d twist = Vector6d::Zero();
  twist.head<3>() = kSpeed * a.head<3>();
  // A binary gripper, as the real Panda's (grasp or open, no speed in between) and as the paper's state has
  // it (open/closed): a command > 0 closes the fingers at full speed (their motors push with up to 70 N),
  // <= 0 opens them. A learned policy then has to get only the command's sign right; with a speed
  // proportional to the command, its averaged mean (near 0 around the grasp) left the fingers half shut.
  const double finger_speed = scene_->arm().model().finger_max_speed;
  scene_->step(twist, a[3] > 0 ? -finger_speed : finger_speed);
  StepResult r;
  if (!scene_->state_is_finite()) {
    r.terminated = true;
    r.failure = "block_stack: the simulation became non-finite";
    r.observation = Eigen::VectorXd::Zero(kObsDim);
    return r;
  }
  r.observation = observation();
  r.reward = reward(r.observation, a);
  return r;
}

cv::Mat BlockStack::render(int width, int height) const {
  const Eigen::Vector3d base = scene_->block_pose(kBaseBlock).translation();
  return scene_->render(width, height, {base});
}

}  // namespace hlt::robot

namespace hlt {

std::unique_ptr<Env> make_block_stack() {
  return std::make_unique<robot::BlockStack>();
}

}  // namespace hlt
