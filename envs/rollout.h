// Running episodes: the episode loop shared by tools, and the simple action sources (zero, constant, uniform
// random) that need no trained policy.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "envs/env.h"

namespace hlt {

// Chooses actions in [-1, 1]^m from observations. Tools plug learned policies in through this interface.
class PolicySource {
 public:
  virtual ~PolicySource() = default;
  virtual std::string describe() const = 0;
  virtual Eigen::VectorXd act(const Eigen::VectorXd& observation) = 0;
  // For a demonstrator that adds noise to what it would do: its noiseless action at the observation of the
  // last act(). Imitation learns from this label while the noisy action is what ran (DART, Laskey et al.
  // 2017): the noise takes the demonstrations off the nominal path, and the labels say how to get back
  // without the noise blurring that. Empty for everything else (the executed action is then the label).
  virtual std::optional<Eigen::VectorXd> intended_action() const { return std::nullopt; }
};

// "zero", "random" (uniform in [-1, 1], generator seeded with `seed`), "constant:V" (every component V) or
// "constant:V1,V2,..." (one value per action component). Throws hlt::Error naming the accepted forms.
std::unique_ptr<PolicySource> make_simple_policy(const std::string& spec, int action_dim, uint64_t seed);

// A policy spec that needs no trained model, for `env`: the simple forms above or "scripted:NAME" (a
// registered scripted policy for this environment, envs/scripted.h). Tools that take a --policy resolve
// everything but their own model-backed forms here.
std::unique_ptr<PolicySource> make_policy_for(const std::string& spec, const Env& env, uint64_t seed);

struct EpisodeStats {
  double episode_return = 0.0;
  int length = 0;
  bool terminated = false;
  bool truncated = false;
  std::string failure;          // set when the simulation failed
  std::optional<bool> success;  // the task's success criterion at the episode's end, if it has one
};

// One step of an episode as the loop saw it: the observation the action was chosen from, the action and the
// environment's answer.
struct Transition {
  int step;
  const Eigen::VectorXd& observation;
  const Eigen::VectorXd& action;
  const StepResult& result;
};

// Resets `env` (with `seed` if given), then steps it with `policy` until the episode ends, or is cut after
// `max_steps` steps if that is positive (then the last step counts as truncated). `on_step`, if set, sees
// every transition; `on_reset`, if set, is called after the reset (e.g. to render the first frame).
EpisodeStats run_episode(Env& env, PolicySource& policy, std::optional<uint64_t> seed,
                         const std::function<void(const Transition&)>& on_step = {},
                         const std::function<void()>& on_reset = {}, int max_steps = 0);

// Episodes step by step as CSV text, one row per transition: episode, step, the observation the action was
// chosen from (obs_i), the action (action_i), reward, done, truncated; values with 17 significant digits.
// Used by hlt_rollout --csv and by the trainer's evaluation traces (eval.trace).
class TrajectoryCsv {
 public:
  TrajectoryCsv(int observation_dim, int action_dim);
  void add(int episode, const Transition& t);
  const std::string& text() const { return text_; }

 private:
  std::string text_;
};

struct ReturnSummary {
  double mean_return = 0.0;
  double std_return = 0.0;  // population standard deviation
  double mean_length = 0.0;
  std::optional<double> success_rate;  // over the episodes whose task has a success criterion
};
ReturnSummary summarize(const std::vector<EpisodeStats>& episodes);

}  // namespace hlt
