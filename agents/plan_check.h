// hlt::PlanCheck: how well a stochastic hybrid's learned models rank the planner's own samples. After a
// planning call it replays every sample's action sequence on copies of the simulator, from the state the
// call planned from, and compares the returns the models predicted with the simulated ones (scored by the
// true reward, and by the run's learned reward model to separate what the reward model costs). Open-loop
// errors on recorded episodes (hlt_model_fit) say how well the models predict the data's actions; this says
// whether they can tell the planner's good samples from its bad ones, which is what the planner needs. It
// reads the simulator's state, which no learner sees: a measuring instrument (hlt_rollout --plan-check).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <ATen/core/Tensor.h>

#include "agents/simulator_model.h"
#include "envs/env.h"
#include "hlt/control/stochastic_hybrid.h"
#include "hlt/nn/reward_model.h"

namespace hlt {

// Spearman's rank correlation of x and y (ties get their mean rank); NaN if either has no spread or the
// sizes differ or are below 2.
double spearman(const std::vector<double>& x, const std::vector<double>& y);

// One planning call's comparison over its K samples (NaN where a metric is undefined: fewer than 2 finite
// samples, or simulated returns with no spread).
struct PlanCheckCall {
  double rank_models = 0;  // Spearman(predicted return, simulated return with the true reward)
  double rank_reward = 0;  // Spearman(simulated return scored by the learned reward, with the true reward)
  // Where the planner's choice lands among the samples' simulated returns: (sum_k w_k J_k - mean J) /
  // (max J - mean J) with the step-0 weights w (1: the best sample, 0: no better than their average).
  double selection = 0;
  double spread = 0;  // max J - mean J: what the best sample gains over the average one
};

class PlanCheck {
 public:
  // `env` (the environment the planner acts in, possibly frame-skipped) must outlive this. `reward`: the
  // run's learned reward model (may be null: rank_reward is then NaN).
  PlanCheck(const Env& env, RewardModel reward);
  // Compares `planner`'s last call, which must have planned from `env`'s current state (before the
  // environment steps with its action). Returns the call's figures and keeps them for summary().
  PlanCheckCall add(const StochasticHybrid& planner);
  // "N calls: ..." with the mean and median of each figure.
  std::string summary() const;
  const std::vector<PlanCheckCall>& calls() const { return calls_; }

 private:
  const Env& env_;
  // Built once: each call's replay starts from the environment's current state
  // (SimulatorRolloutModel::begin).
  SimulatorRolloutModel truth_;                    // the true reward
  std::unique_ptr<SimulatorRolloutModel> scored_;  // the learned reward (null without one)
  std::vector<PlanCheckCall> calls_;
};

}  // namespace hlt
