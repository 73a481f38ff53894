#include "envs/robot/block_stack_expert.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "envs/robot/block_stack.h"
#include "hlt/util/error.h"

namespace hlt::robot {

namespace {

using B = BlockStack;

constexpr double kGain = 5.0;             // 1/s: velocity per metre of error
constexpr double kApproachHeight = 0.07;  // tool centre point over the block's centre before descending
constexpr double kCarryClearance = 0.03;  // the block's bottom over the base's top while moving
constexpr double kRetreatHeight = 0.05;   // tool centre point over the stacked block's centre at the end
constexpr double kOpen = 0.035;           // m: fingers well clear of a 5 cm block
constexpr double kGraspBand = 0.012;      // m: tool centre point over the block's centre where it closes
// Graded gripper commands (see nominal_action): over the last kGripRamp before the fingers switch, the
// command moves from fully open (or closed) to kGripEdge short of the switch.
constexpr double kGripRamp = 0.03;  // m
constexpr double kGripEdge = 0.2;   // |command| where the switch happens
// The command's size at a height over the switching height: 1 from kGripRamp up, kGripEdge at (or below) it.
double graded(double height) {
  return std::min(1.0, kGripEdge + (1.0 - kGripEdge) * std::max(height, 0.0) / kGripRamp);
}
// Carrying (see nominal_action): the block is "over the base" within kOverBase of its axis and "away" from
// kAwayFromBase on; it moves sideways at full speed once within kClearBand of the carrying height, not at
// all from 3 kClearBand under it.
constexpr double kOverBase = 0.004;      // m
constexpr double kAwayFromBase = 0.02;   // m
constexpr double kClearBand = 0.01;      // m
double ramp(double x) { return std::clamp(x, 0.0, 1.0); }

// The observation's parts the phases are decided on.
struct View {
  Eigen::Vector3d ee, block, base, stack;
  double opening = 0;  // m, mean of the two fingers
  bool held = false;
};

View view(const Eigen::VectorXd& o) {
  check(o.size() == B::kObsDim, "scripted block_stack expert: observation has {} values, expected {}",
        o.size(), B::kObsDim);
  View v;
  v.ee = o.segment<3>(B::kEe);
  v.block = o.segment<3>(B::kBlock);
  v.base = o.segment<3>(B::kBase);
  v.stack = B::stack_point(o);
  v.opening = o[B::kGripper] * B::kFingerTravel;
  v.held = B::grasped(o);
  return v;
}

// The block sits on the base (centred, at the stacking height, a little slack for it settling).
bool on_base(const View& v) {
  return (v.block.head<2>() - v.base.head<2>()).norm() < 0.01 && std::abs(v.block.z() - v.stack.z()) < 0.003;
}

}  // namespace

StackExpert::StackExpert(uint64_t seed, double noise) : noise_(noise), rng_(seed) {
  check(noise >= 0 && std::isfinite(noise), "scripted block_stack expert: noise must be >= 0, got {}", noise);
}

std::string StackExpert::describe() const {
  return fmt::format("scripted block_stack expert (noise {})", noise_);
}

StackExpert::Phase StackExpert::phase(const Eigen::VectorXd& o) {
  const View v = view(o);
  if (v.held) {
    // Names for the parts of one velocity field (nominal_action), not switches of the action.
    if (on_base(v)) return Phase::kRelease;
    if ((v.base - v.block).head<2>().norm() < kAwayFromBase) return Phase::kLower;
    if (v.block.z() < v.stack.z() + kCarryClearance - kClearBand) return Phase::kLift;
    return Phase::kMove;
  }
  if (on_base(v) || ((v.block.head<2>() - v.base.head<2>()).norm() < B::kPlaceXY &&
                     std::abs(v.block.z() - v.stack.z()) < B::kPlaceZ)) {
    return v.opening < kOpen ? Phase::kRelease : Phase::kRetreat;
  }
  const double e = (v.block.head<2>() - v.ee.head<2>()).norm();
  const bool low = v.ee.z() < v.block.z() + kApproachHeight - 0.01;
  // Once low, a wider band keeps the descent going under noise; a larger error goes back up first.
  if (e < 0.006 || (low && e < 0.012)) {
    return v.ee.z() - v.block.z() < kGraspBand ? Phase::kClose : Phase::kDescend;
  }
  return Phase::kApproach;
}

Eigen::Vector4d StackExpert::nominal_action(const Eigen::VectorXd& o) {
  const View v = view(o);
  Eigen::Vector3d vel = Eigen::Vector3d::Zero();
  double grip = -1.0;
  switch (phase(o)) {
    case Phase::kApproach: {
      const Eigen::Vector3d over = v.block + Eigen::Vector3d(0, 0, kApproachHeight);
      vel = kGain * (over - v.ee);
      // Well below the approach height, rise before moving sideways so the open fingers miss the block.
      if (v.ee.z() < over.z() - 0.02) vel.head<2>().setZero();
      break;
    }
    case Phase::kDescend:
      vel = kGain * (v.block - v.ee);
      // The environment's gripper acts on the command's sign only, so the expert is free to grade it. A
      // command that jumps from -1 to +1 at the grasp height gives a cloned policy one "close" label per
      // demonstration among dozens of "open" ones a few millimetres above, and its regressed command at the
      // bottom stayed negative (an open hand at the grasp). Graded, the labels approach the switch as the
      // tool approaches the block, and the sign change is where the expert closes.
      grip = -graded(v.ee.z() - v.block.z() - kGraspBand);
      break;
    case Phase::kClose:
      vel.head<2>() = kGain * (v.block - v.ee).head<2>();
      grip = 1.0;
      break;
    case Phase::kLift:
    case Phase::kMove:
    case Phase::kLower: {
      // One velocity field, continuous in the state, for lift, move and lower: a cloned policy smooths
      // switches between them, and with switches it moved sideways before the block was up and lowered it
      // short of the base, where the expert's data say "lower" only within 4 mm of the base's axis.
      // How far from over the base: 1 away from it (carry at the carrying height), 0 over it (lower onto it).
      const Eigen::Vector2d e = (v.base - v.block).head<2>();
      const double away = ramp((e.norm() - kOverBase) / (kAwayFromBase - kOverBase));
      const double carry_z = v.stack.z() + kCarryClearance;
      // Aim a little below the stacking height, so the block reaches the base at a few cm/s at most.
      const double target_z = v.stack.z() - 0.004 + (kCarryClearance + 0.004) * away;
      vel.z() = std::max(kGain * (target_z - v.block.z()), -0.05);
      // Sideways only as the block clears the base's height (moving low would drag it or knock it against
      // the base); over the base, always, to centre it.
      // The factor applies after the speed limit, so that the command itself (not only a saturated
      // velocity) rises with the height.
      const double clear = ramp((v.block.z() - (carry_z - 3 * kClearBand)) / (2 * kClearBand));
      Eigen::Vector2d sideways = kGain * e;
      if (sideways.norm() > B::kSpeed) sideways *= B::kSpeed / sideways.norm();
      vel.head<2>() = std::max(clear, 1.0 - away) * sideways;
      // Graded towards the release as the block comes down onto the base, for the same reason as the
      // descent's command; fully closed while away from the base.
      grip = 1.0 - (1.0 - graded(v.block.z() - v.stack.z())) * (1.0 - away);
      break;
    }
    case Phase::kRelease:
      break;
    case Phase::kRetreat:
      vel.z() = kGain * (v.block.z() + kRetreatHeight - v.ee.z());
      break;
  }
  Eigen::Vector4d a;
  a.head<3>() = vel / B::kSpeed;
  // Scaled as a whole, so that a saturated command keeps its direction.
  const double biggest = a.head<3>().cwiseAbs().maxCoeff();
  if (biggest > 1.0) a.head<3>() /= biggest;
  a[3] = grip;
  return a;
}

Eigen::VectorXd StackExpert::act(const Eigen::VectorXd& observation) {
  Eigen::Vector4d a = nominal_action(observation);
  intended_ = Eigen::VectorXd(a);
  for (int i = 0; i < 4; ++i)
    a[i] += noise_ * normal_(rng_);
  return a.cwiseMax(-1.0).cwiseMin(1.0);
}

}  // namespace hlt::robot

namespace hlt {

std::unique_ptr<PolicySource> make_block_stack_expert(uint64_t seed) {
  return std::make_unique<robot::StackExpert>(seed);
}

}  // namespace hlt
