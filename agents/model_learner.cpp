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
  torch::Tensor loss_f = dynamics_->loss(b.states, b.actions, b.next_states);
  torch::Tensor loss_r = reward_->td_loss(b.states, b.actions, b.rewards, b.next_states, b.next_actions,
                                          b.dones, options_.reward_gamma);
  optimizer_->zero_grad();
  (loss_f + options_.reward_weight * loss_r).backward();
  optimizer_->step();
  return {loss_f.item<double>(), loss_r.item<double>()};
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
