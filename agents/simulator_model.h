// hlt::SimulatorRolloutModel: a RolloutModel that steps a copy of the environment itself instead of learned
// models, one snapshot per rollout. With it the stochastic hybrid's planner (its policy samples, horizon,
// weights) acts with a perfect model and the true reward: the ceiling that better learned models could
// reach with that planner (hlt_rollout --plan-on simulator). Given a learned reward model it scores the
// simulated transitions with that model instead of the true reward (--plan-on simulator-dynamics), which
// separates what the learned dynamics cost from what the learned reward costs. It reads the real
// environment's state, which no learner sees, so it is a measuring instrument, not a method.
#pragma once

#include <memory>
#include <vector>

#include "envs/env.h"
#include "hlt/control/rollout_model.h"

namespace hlt {

class SimulatorRolloutModel : public RolloutModel {
 public:
  // `env` (a registered environment, possibly frame-skipped) must outlive this: every planning call starts
  // from its current state. States, actions and rewards are exchanged as `dtype`.
  SimulatorRolloutModel(const Env& env, at::ScalarType dtype, RewardModel reward = nullptr);
  int64_t state_dim() const override { return env_.observation_dim(); }
  int64_t action_dim() const override { return env_.action_dim(); }
  at::ScalarType dtype() const override { return dtype_; }
  // Every rollout starts from the real environment's snapshot (`start` is only checked against its
  // observation's size).
  void begin(int64_t batch, const at::Tensor& start) override;
  // Rollout k: restore its snapshot, step the copy with action k, keep the new snapshot. A rollout whose
  // episode ended (terminated or cut by the time limit) stays where it ended and earns 0 from then on (also
  // with a learned reward model).
  void step(const at::Tensor& states, const at::Tensor& actions, at::Tensor& next_states,
            at::Tensor& rewards) override;

 private:
  const Env& env_;
  std::unique_ptr<Env> sim_;
  at::ScalarType dtype_;
  RewardModel
      reward_;  // if set: its prediction of every step (RewardModelImpl::predict), not the true reward
  std::vector<EnvState> snapshots_;
  std::vector<bool> ended_;
};

}  // namespace hlt
