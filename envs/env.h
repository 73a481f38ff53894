// hlt::Env: the interface every task implements, analytic or simulated.
//
// Agents always act in [-1, 1]^m; each environment scales to its own forces. Observations and actions are
// Eigen vectors (no tensors at this boundary, so simulation code stays free of LibTorch). The base class
// validates actions, counts steps against the time limit, keeps a terminal state apart from a time-limit
// cut, and turns a non-finite simulation into a reported failure instead of NaN observations.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace hlt {

struct StepResult {
  Eigen::VectorXd observation;
  double reward = 0.0;
  bool terminated = false;  // a true terminal state (fell, or the simulation failed)
  bool truncated = false;   // the episode's time limit cut it
  std::string failure;      // set when the simulation produced non-finite values (then terminated is set)
  bool done() const { return terminated || truncated; }
};

// Where an environment's observations typically lie: component i around offset[i], spread over about
// scale[i] (> 0). Learners that normalise their inputs use (o - offset) / scale; the numbers are the task's
// physical ranges (its workspace, its forces), fixed, so a normalised network means the same on any data.
// With `reference` (empty, or one entry per component: -1 or another component's index r), component i is
// read as o_i - o_r before its offset and scale: a position relative to another, over the range it spans.
struct ObservationScale {
  Eigen::VectorXd offset, scale;
  Eigen::VectorXi reference;
};

// A snapshot of an environment: simulator state, random generator and step counter.
struct EnvState {
  std::vector<double> sim;
  std::mt19937_64 rng;
  int elapsed_steps = 0;
  bool needs_reset = true;
  Eigen::VectorXd last_observation;
  std::vector<EnvState> wrapped;  // a wrapper's inner environment (empty otherwise)
};

class Env {
 public:
  virtual ~Env() = default;

  virtual std::string name() const = 0;
  virtual int observation_dim() const = 0;
  virtual int action_dim() const = 0;
  // The episode limit in this environment's own steps.
  virtual int max_episode_steps() const = 0;
  // Simulated seconds per step.
  virtual double dt() const = 0;

  // Starts an episode. With a seed the environment's generator is re-seeded first; without one the episode
  // continues the generator's stream (so successive episodes differ but a run stays reproducible).
  Eigen::VectorXd reset(std::optional<uint64_t> seed = std::nullopt);
  // Advances one step. Throws hlt::Error for an action of the wrong size or with NaN/Inf entries, and for a
  // step after the episode ended without reset().
  StepResult step(const Eigen::VectorXd& action);
  int elapsed_steps() const { return elapsed_; }

  EnvState save_state() const;
  void restore_state(const EnvState& state);

  // An image of the current state (BGR, 8-bit).
  virtual cv::Mat render(int width = 480, int height = 360) const = 0;

  // Tasks with a success criterion (the robot tasks) say whether it holds in the current state; the
  // episode loop asks at an episode's end. Others have none (nullopt).
  virtual std::optional<bool> episode_success() const { return std::nullopt; }
  // Tasks whose observation components have very different units (metres next to newtons) declare their
  // typical ranges (policy.normalize_inputs uses them); others none.
  virtual std::optional<ObservationScale> observation_scale() const { return std::nullopt; }

 protected:
  // Draws an initial state from `rng` and returns the first observation.
  virtual Eigen::VectorXd reset_impl(std::mt19937_64& rng) = 0;
  // Advances with a validated action (right size, finite; not clipped: environments clip where their
  // model says so). Implementations set terminated (and may set truncated); the base applies the time limit.
  virtual StepResult step_impl(const Eigen::VectorXd& action) = 0;
  virtual std::vector<double> save_sim() const = 0;
  virtual void restore_sim(const std::vector<double>& sim) = 0;
  // Wrappers snapshot the environment they wrap here.
  virtual void save_wrapped(EnvState& state) const {}
  virtual void restore_wrapped(const EnvState& state) {}

 private:
  std::mt19937_64 rng_{0};
  int elapsed_ = 0;
  bool needs_reset_ = true;
  Eigen::VectorXd last_observation_;
};

// Repeats each action `k` times and sums the rewards; stops early when the inner episode ends. The time
// limit stays counted in the inner environment's steps, so returns keep the environment's own scale.
class FrameSkip : public Env {
 public:
  FrameSkip(std::unique_ptr<Env> inner, int k);
  std::string name() const override { return inner_->name(); }
  int observation_dim() const override { return inner_->observation_dim(); }
  int action_dim() const override { return inner_->action_dim(); }
  int max_episode_steps() const override { return (inner_->max_episode_steps() + k_ - 1) / k_; }
  double dt() const override { return inner_->dt() * k_; }
  cv::Mat render(int width, int height) const override { return inner_->render(width, height); }
  std::optional<bool> episode_success() const override { return inner_->episode_success(); }
  std::optional<ObservationScale> observation_scale() const override { return inner_->observation_scale(); }
  int frame_skip() const { return k_; }
  // Simulator steps taken in the current episode.
  int inner_elapsed_steps() const { return inner_->elapsed_steps(); }
  // The number of simulator steps the last step() took (k, or fewer when the episode ended).
  int last_step_frames() const { return last_frames_; }
  Env& inner() { return *inner_; }

 protected:
  Eigen::VectorXd reset_impl(std::mt19937_64& rng) override;
  StepResult step_impl(const Eigen::VectorXd& action) override;
  std::vector<double> save_sim() const override { return {}; }
  void restore_sim(const std::vector<double>& sim) override {}
  void save_wrapped(EnvState& state) const override;
  void restore_wrapped(const EnvState& state) override;

 private:
  std::unique_ptr<Env> inner_;
  int k_;
  int last_frames_ = 0;
};

}  // namespace hlt
