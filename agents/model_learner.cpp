#include "agents/model_learner.h"

#include <torch/torch.h>

#include "hlt/core/checkpoint.h"

namespace hlt {

ModelLearner::ModelLearner(DynamicsModel dynamics, RewardModel reward, const ModelLearnerOptions& options)
    : options_(options), dynamics_(std::move(dynamics)), reward_(std::move(reward)) {
  std::vector<torch::Tensor> params = dynamics_->parameters();
  for (auto& p : reward_->parameters())
    params.push_back(p);
  optimizer_ = std::make_unique<FlatAdam>(params, FlatAdamOptions{options.lr});
}

ModelLosses ModelLearner::update(const Batch& b) {
  // Both backward passes are written by hand (no autograd graph): each writes its own parameters'
  // gradients, so the flat gradient buffer needs no zeroing.
  c10::InferenceMode guard;
  ModelLosses losses;
  losses.dynamics = dynamics_->loss_with_gradient(b.states, b.actions, b.next_states);
  losses.reward =
      reward_->td_loss_with_gradient(b.states, b.actions, b.rewards, b.next_states, b.next_actions, b.dones,
                                     options_.reward_gamma, options_.reward_weight);
  optimizer_->step();
  return losses;
}

void ModelLearner::save(CheckpointWriter& w) const {
  w.add_module("dynamics", *dynamics_);
  w.add_module("reward", *reward_);
  save_training_state(w);
}

void ModelLearner::load(CheckpointReader& r) {
  r.load_module("dynamics", *dynamics_);
  r.load_module("reward", *reward_);
  load_training_state(r);
}

void ModelLearner::save_training_state(CheckpointWriter& w) const {
  optimizer_->save(w, "models");
}

void ModelLearner::load_training_state(CheckpointReader& r) {
  optimizer_->load(r, "models");
}

}  // namespace hlt
