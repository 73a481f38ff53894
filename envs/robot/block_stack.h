// BlockStack: the paper's block-stacking task on the simulated Panda. The agent moves the gripper (tool
// pointing down, orientation held) at a commanded velocity and opens or closes its fingers; the block to be
// stacked starts under the gripper, the base block somewhere in the workspace; the episode is a success when
// the block rests on the base at the end and the gripper has let go of it. Reward: the paper's staged
// distance r_stage(s) - 1e-6 (|F_ee| + |a|) (see reward()).
#pragma once

#include <memory>

#include <Eigen/Core>

#include "envs/env.h"
#include "envs/robot/tabletop.h"

namespace hlt::robot {

class BlockStack : public Env {
 public:
  static constexpr double kBlockHalf = 0.025;    // both blocks are 5 cm cubes
  static constexpr double kFingerTravel = 0.04;  // the Panda's: the observed gripper value is opening / this
  static constexpr double kSpeed = 0.15;         // m/s per axis at |a_i| = 1
  static constexpr int kSteps = 200;             // of 0.1 s
  // The tool's workspace (robot base frame); its floor keeps the fingertips 1 cm off the table.
  static constexpr double kXMin = 0.3, kXMax = 0.75, kYMin = -0.3, kYMax = 0.35, kZMin = 0.015, kZMax = 0.3;
  // The block starts within kJitter (per axis) of (kBlockX, kBlockY), the gripper kStartHeight over that
  // spot.
  static constexpr double kBlockX = 0.5, kBlockY = -0.1, kJitter = 0.01, kStartHeight = 0.12;
  // The base starts within kJitter (per axis) of (kBaseX, kBaseY), its yaw anywhere. A fixed spot, as in the
  // paper: its state has no target position (the stacking point is a constant of the task) and the arm
  // starts at the same spot every time. (hlt's first version drew the base anywhere in a 25 x 40 cm
  // rectangle: from 1-10 demonstrations a policy then has to generalise over the target's position, which
  // the paper's task does not ask.)
  static constexpr double kBaseX = 0.55, kBaseY = 0.1;
  // Success tolerances: the block's centre over the base's, its height over the base's, and the fingers
  // clear of its faces.
  static constexpr double kPlaceXY = 0.015, kPlaceZ = 0.005, kReleasedOpening = kBlockHalf + 0.004;
  static constexpr double kCarryWeight = 1.25;  // the paper's weight on the carrying stage's distance
  static constexpr double kWrenchCost = 1e-6;

  // Observation layout (16 numbers).
  static constexpr int kEe = 0, kBlock = 3, kBase = 6, kGripper = 9, kForce = 10, kTorque = 13, kObsDim = 16;

  enum class Stage { kReach, kCarry };

  BlockStack();
  std::string name() const override { return "block_stack"; }
  int observation_dim() const override { return kObsDim; }
  int action_dim() const override { return 4; }
  int max_episode_steps() const override { return kSteps; }
  double dt() const override { return 0.1; }
  cv::Mat render(int width = 480, int height = 360) const override;

  // Whether the fingers hold the block: both pads closed on its faces (the mean opening within a few mm of
  // its half width) and its centre between the pads.
  static bool grasped(const Eigen::VectorXd& observation);
  static Stage stage(const Eigen::VectorXd& observation) {
    return grasped(observation) ? Stage::kCarry : Stage::kReach;
  }
  // Where the block's centre (and so the tool centre point holding it) goes: one block size over the base.
  static Eigen::Vector3d stack_point(const Eigen::VectorXd& observation);
  // r_stage: -1.25 |p_ee - p_stack| while grasped, else -|p_ee - p_block| - 1.25 |p_block - p_stack|.
  static double stage_reward(const Eigen::VectorXd& observation);
  // stage_reward - 1e-6 (|F_ee| + |a|) with F_ee the observation's external force.
  static double reward(const Eigen::VectorXd& observation, const Eigen::Vector4d& action);

  // Whether the block rests on the base (centre within kPlaceXY of the base's in the plane, height one
  // block size over it within kPlaceZ, slower than 1 cm/s) and the gripper is open clear of it.
  bool success() const;
  std::optional<bool> episode_success() const override { return success(); }
  // The workspace around the two blocks' spots (positions over a few cm), the opening, the wrench (a held
  // block's weight, contact forces of a few N).
  std::optional<ObservationScale> observation_scale() const override;

  Eigen::VectorXd observation() const;
  const Tabletop& scene() const { return *scene_; }
  Tabletop& scene() { return *scene_; }
  // The arm at its start, fingers open, the block at (x, y, yaw) and the base at (x, y, yaw), both at rest
  // on the table (test scenarios).
  void place(const Eigen::Vector3d& block, const Eigen::Vector3d& base);
  // The external force on the hand (N, world): Tabletop::external_force (the wrist force less the hand's
  // weight, corrected by its m a).
  Eigen::Vector3d external_force() const;

 protected:
  Eigen::VectorXd reset_impl(std::mt19937_64& rng) override;
  StepResult step_impl(const Eigen::VectorXd& action) override;
  std::vector<double> save_sim() const override { return scene_->save_state(); }
  void restore_sim(const std::vector<double>& sim) override { scene_->restore_state(sim); }

 private:
  std::unique_ptr<Tabletop> scene_;
  Vector7d home_ = Vector7d::Zero();
};

}  // namespace hlt::robot
