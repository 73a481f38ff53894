// hlt::RolloutModel: what the stochastic planner rolls its K samples through, one step of the whole batch at
// a time. The methods plan on their learned dynamics and reward models (LearnedRolloutModel); the tools can
// also plan on a copy of the environment itself (agents/simulator_model.h), which measures what the same
// planner does with a perfect model.
#pragma once

#include <cstdint>
#include <vector>

#include <ATen/core/Tensor.h>

#include "hlt/nn/batched_forward.h"
#include "hlt/nn/dynamics_model.h"
#include "hlt/nn/reward_model.h"

namespace hlt {

class RolloutModel {
 public:
  virtual ~RolloutModel() = default;
  virtual int64_t state_dim() const = 0;
  virtual int64_t action_dim() const = 0;
  // The dtype of the states, actions and rewards it reads and writes.
  virtual at::ScalarType dtype() const = 0;
  // Starts a planning call of `batch` rollouts, all from `start` [n] (the state the planner acts in).
  virtual void begin(int64_t batch, const at::Tensor& start) = 0;
  // Writes next_states [batch, n] and rewards [batch] for states [batch, n] and actions [batch, m] (rows
  // contiguous, dtype()). The outputs are caller-owned, contiguous and of dtype().
  virtual void step(const at::Tensor& states, const at::Tensor& actions, at::Tensor& next_states,
                    at::Tensor& rewards) = 0;
};

// rows [B, n] (rows contiguous) clamped per column to [low, high] ([n] each, the rows' dtype), in place.
void clamp_rows(at::Tensor& rows, const at::Tensor& low, const at::Tensor& high);

// How the stochastic planners use an ensemble of dynamics models (model.ensemble > 1).
struct EnsembleOptions {
  // The other members; `dynamics` (LearnedRolloutModel's first argument) is the first. Empty: one model.
  std::vector<DynamicsModel> members;
  // Every step's reward is lowered by this times the members' disagreement on the next state,
  // u = sqrt(mean_i var_m(s'_{m,i}) / sigma_i^2), with sigma the first member's learned noise scale (so u
  // counts noise standard deviations). Why: where the members disagree the models do not know what the
  // action does, and the planner's weights would otherwise favour the samples whose errors flatter them
  // most; penalised there, the planner keeps to what the models know (MOPO, Yu et al. 2020).
  double disagreement_penalty = 0;
};

// The learned dynamics and reward models, as one batched pass (ModelForward). With `clamp_to_domain` every
// predicted state is kept inside the dynamics model's domain (the per-dimension range of the states it was
// trained on), once it has one. A reward model of the next state scores each step's (clamped) prediction.
// With an ensemble (EnsembleOptions) the predicted next state is the members' mean, what the reward and the
// next step read, and the disagreement penalty is taken off each step's reward.
class LearnedRolloutModel : public RolloutModel {
 public:
  LearnedRolloutModel(DynamicsModel dynamics, RewardModel reward, bool clamp_to_domain,
                      EnsembleOptions ensemble = {});
  int64_t state_dim() const override { return dynamics_->options().state_dim; }
  int64_t action_dim() const override { return dynamics_->options().action_dim; }
  at::ScalarType dtype() const override { return dynamics_->fc1->weight.scalar_type(); }
  void begin(int64_t batch, const at::Tensor& start) override;
  void step(const at::Tensor& states, const at::Tensor& actions, at::Tensor& next_states,
            at::Tensor& rewards) override;

 private:
  DynamicsModel dynamics_;
  RewardModel reward_;
  ModelForward forward_;
  bool clamp_to_domain_;
  EnsembleOptions ensemble_;
  at::Tensor penalty_;  // the last step's disagreement u, [batch]
};

}  // namespace hlt
