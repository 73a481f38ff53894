// Walker: the locomotion task of PyBullet's WalkerBase environments (HopperBulletEnv, HalfCheetahBulletEnv,
// AntBulletEnv), written once for any robot a WalkerSpec describes: a Bullet world with the stadium's ground
// plane, torques power * power_coef * clip(a, -1, 1) held over 4 sub-steps of 0.004125 s, the observation
// [8 body values, joint positions and speeds, foot contacts], and the reward alive + progress + electricity
// + joints-at-limit (docs/ENVIRONMENTS.md gives every term and the checks against PyBullet).
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "envs/bullet/robot.h"
#include "envs/bullet/world.h"
#include "envs/env.h"
#include "envs/locomotion/model.h"

namespace hlt::locomotion {

// When the robot counts as alive (+1; otherwise -1). Every rule given must hold.
struct AliveRule {
  std::optional<double> min_z;          // the torso's COM is higher than this
  std::optional<double> max_abs_pitch;  // |torso pitch| is below this (rad)
  std::vector<int> forbidden_feet;  // indices into WalkerSpec::feet that did not touch the floor last step
};

struct WalkerSpec {
  std::string name;  // the registry name
  Model model;
  std::string torso = "torso";  // the body whose pose and velocity the observation reports
  double power = 1.0;
  std::vector<std::string> feet;  // bodies whose floor contact the observation reports
  AliveRule alive;
  bool ends_when_not_alive = true;  // false: being "dead" only costs reward (HalfCheetah)
  double ground_friction = 0.8;
  double ground_restitution = 0.5;
  bool top_view = false;  // render a top view beside the side view
};

class Walker : public Env {
 public:
  static constexpr double kDt = 0.0165;
  static constexpr int kSubsteps = 4;
  static constexpr int kMaxSteps = 1000;
  static constexpr double kTargetX = 1000.0;  // the walk target, 1 km ahead along x
  static constexpr double kTargetY = 0.0;
  static constexpr double kElectricityCost = -2.0;
  static constexpr double kStallTorqueCost = -0.1;
  static constexpr double kJointsAtLimitCost = -0.1;

  explicit Walker(WalkerSpec spec);

  std::string name() const override { return spec_.name; }
  int observation_dim() const override { return 8 + 2 * action_dim() + static_cast<int>(feet_.size()); }
  int action_dim() const override { return static_cast<int>(model_.joints.size()); }
  int max_episode_steps() const override { return kMaxSteps; }
  double dt() const override { return kDt; }
  // A side view following the torso (and, with WalkerSpec::top_view, a top view beside it).
  cv::Mat render(int width = 480, int height = 360) const override;

  // The reward of the last step, term by term.
  struct Terms {
    double alive = 0.0;
    double progress = 0.0;
    double electricity = 0.0;
    double joints_at_limit = 0.0;
    int joints_at_limit_count = 0;
    double sum() const { return alive + progress + electricity + joints_at_limit; }
  };
  const Terms& last_terms() const { return terms_; }
  // -(distance from the parts' mean position to the target) / dt, as of the last step or reset.
  double potential() const { return potential_; }
  double initial_z() const { return initial_z_; }
  // 1 for each foot that touched the floor in the last step (what the next observation will carry).
  const std::vector<double>& feet_contact() const { return feet_contact_; }
  // The mean (x, y) over PyBullet's "parts" (every link, the base when it floats, and the floor at the
  // origin) that the potential measures from.
  Eigen::Vector2d parts_mean() const;

  // Makes the next reset start the actuated joints at `q` (action order) instead of the drawn angles (the
  // generator advances as usual), e.g. to compare with PyBullet from identical states.
  void set_next_start(const Eigen::VectorXd& q);

  const WalkerSpec& spec() const { return spec_; }
  const BuiltModel& model() const { return model_; }
  bullet::Robot& robot() { return *robot_; }
  const bullet::Robot& robot() const { return *robot_; }
  bullet::World& world() { return *world_; }
  int torso_link() const { return torso_; }

 protected:
  Eigen::VectorXd reset_impl(std::mt19937_64& rng) override;
  StepResult step_impl(const Eigen::VectorXd& action) override;
  std::vector<double> save_sim() const override;
  void restore_sim(const std::vector<double>& sim) override;

 private:
  // PyBullet's calc_state: the observation (carrying the feet contacts as they are now), and as side results
  // the torso height and pitch, the scaled joint speeds, the joints-at-limit count and the potential of the
  // current state (potential_next_).
  Eigen::VectorXd observe();
  void refresh_feet_contact();

  WalkerSpec spec_;
  BuiltModel model_;
  std::unique_ptr<bullet::World> world_;
  bullet::Robot* robot_ = nullptr;
  int torso_ = -1;
  std::vector<int> feet_;
  std::vector<double> start_state_;  // the robot at the zero configuration, at rest
  std::optional<Eigen::VectorXd> next_start_;

  // Episode state (part of snapshots).
  double potential_ = 0.0;
  double initial_z_ = 0.0;
  std::vector<double> feet_contact_;

  double view_size_ = 3.0;  // metres across a rendered view

  // Side results of observe().
  double potential_next_ = 0.0;
  double z_ = 0.0, pitch_ = 0.0;
  Eigen::VectorXd joint_speeds_;
  int at_limit_ = 0;
  Terms terms_;
};

}  // namespace hlt::locomotion
