// StackExpert: a hand-written demonstrator for block_stack that reads only the observation (no memory
// between steps, so it recovers from its own noise and from a slipped block): approach over the block,
// descend, close, lift, move over the base, descend until the block sits on it, open, retreat upwards.
// Gaussian noise of a chosen size is added to every action component before clipping, so that
// demonstrations cover the states around the nominal path. The gripper command is graded (its sign is all
// the environment reads): it approaches the switch as the tool descends to the grasp and as the block comes
// down onto the base, so that a cloned policy can place the switch from a few demonstrations.
// Lifting, carrying and lowering are one velocity field, continuous in the state, for the same reason.
#pragma once

#include <cstdint>
#include <random>
#include <string>

#include <Eigen/Core>

#include "envs/rollout.h"

namespace hlt::robot {

class StackExpert : public PolicySource {
 public:
  enum class Phase { kApproach, kDescend, kClose, kLift, kMove, kLower, kRelease, kRetreat };

  StackExpert(uint64_t seed, double noise = kNoise);
  std::string describe() const override;
  Eigen::VectorXd act(const Eigen::VectorXd& observation) override;
  std::optional<Eigen::VectorXd> intended_action() const override { return intended_; }

  // The phase the observation puts the task in, and the noiseless action for it.
  static Phase phase(const Eigen::VectorXd& observation);
  static Eigen::Vector4d nominal_action(const Eigen::VectorXd& observation);

  static constexpr double kNoise = 0.1;  // standard deviation, in action units

 private:
  double noise_;
  std::optional<Eigen::VectorXd> intended_;  // nominal_action of the last act()
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
};

}  // namespace hlt::robot
