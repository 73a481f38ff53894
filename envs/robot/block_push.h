// BlockPush: the paper's block-pushing task on the simulated Sawyer. The tool moves in a plane over the table
// at the agent's planar velocity command; the state is the paper's end-effector -> block and block ->
// target, each (dx, dy, dyaw), followed by what the robot knows of itself: the tool's position in the
// workspace (x, y, from the workspace's centre) and the filtered velocity command it is moving at (vx, vy).
// Without the last four the next state is not a function of state and action (the workspace clamp and the
// filter decide how far the tool moves), and a learned model cannot fit it. The reward -5 |p_b2t| - 10
// |p_ee2b| - 0.01 |a|^2; 100 steps of 0.1 s; block and target placed at random in the workspace at reset (the
// block 7 cm inside its edges, so that the tool can reach round it); success when the block's centre ends
// within 3 cm of the target.
#pragma once

#include <memory>

#include <Eigen/Core>

#include "envs/env.h"
#include "envs/robot/tabletop.h"

namespace hlt::robot {

class BlockPush : public Env {
 public:
  // The workspace of the authors' Sawyer code (robot base frame) and its velocity scale.
  static constexpr double kXMin = 0.5, kXMax = 0.75, kYMin = -0.2, kYMax = 0.25;
  static constexpr double kSpeed = 0.4;           // m/s at |a_i| = 1
  static constexpr double kFilter = 0.5;          // share of the previous command kept each step
  static constexpr double kToolHeight = 0.025;    // the tool tip's centre, at the block's mid-height
  static constexpr double kSuccessRadius = 0.03;  // m
  static constexpr int kSteps = 100;
  static constexpr int kObservationDim = 10;

  BlockPush();
  std::string name() const override { return "block_push"; }
  int observation_dim() const override { return kObservationDim; }
  int action_dim() const override { return 2; }
  int max_episode_steps() const override { return kSteps; }
  double dt() const override { return 0.1; }
  cv::Mat render(int width = 480, int height = 360) const override;

  // The paper's reward for an observation (its first six components) and (clipped) action.
  static double reward(const Eigen::VectorXd& observation, const Eigen::Vector2d& action);
  // Whether the block's centre is within kSuccessRadius of the target (in the table's plane).
  bool success() const;
  std::optional<bool> episode_success() const override { return success(); }
  // The positions over the workspace's 10-20 cm, the yaws over their +-pi: raw, a yaw of 2 rad outweighs
  // every position the reward depends on.
  std::optional<ObservationScale> observation_scale() const override;
  const Eigen::Vector3d& target() const { return target_; }  // x, y, yaw
  const Tabletop& scene() const { return *scene_; }
  Tabletop& scene() { return *scene_; }
  Eigen::VectorXd observation() const;
  // Moves block and target (test scenarios); positions in the table plane.
  void place(const Eigen::Vector3d& block_xy_yaw, const Eigen::Vector3d& target_xy_yaw);

 protected:
  Eigen::VectorXd reset_impl(std::mt19937_64& rng) override;
  StepResult step_impl(const Eigen::VectorXd& action) override;
  std::vector<double> save_sim() const override;
  void restore_sim(const std::vector<double>& sim) override;

 private:
  std::unique_ptr<Tabletop> scene_;
  Vector7d home_ = Vector7d::Zero();
  Eigen::Vector3d target_ = Eigen::Vector3d::Zero();
};

}  // namespace hlt::robot
