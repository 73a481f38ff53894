#include "agents/model_learner.h"

#include <cmath>

#include <torch/torch.h>

#include "hlt/core/checkpoint.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {
const char* const kDomainLow = "models.domain_low";
const char* const kDomainHigh = "models.domain_high";
}  // namespace

ModelLearner::ModelLearner(DynamicsModel dynamics, RewardModel reward, const ModelLearnerOptions& options,
                           std::vector<DynamicsModel> ensemble)
    : options_(options),
      dynamics_(std::move(dynamics)),
      members_(std::move(ensemble)),
      reward_(std::move(reward)) {
  check(!reward_->options().reads_next_state || options_.reward_gamma == 0.0,
        "a reward model of the next state (model.reward_input next_state) is fitted by regression: "
        "model.reward_gamma must be 0, got {}",
        options_.reward_gamma);
  check(options_.hard_mining >= 1, "model.hard_mining must be >= 1, got {}", options_.hard_mining);
  check(options_.hard_mining == 1 || options_.rollout_steps == 1,
        "model.hard_mining {} chooses among single transitions: it needs model.rollout_steps 1, got {}",
        options_.hard_mining, options_.rollout_steps);
  std::vector<torch::Tensor> params = dynamics_->parameters();
  for (auto& p : reward_->parameters())
    params.push_back(p);
  // After the reward model: a single model's flat buffer is laid out as it always was.
  for (DynamicsModel& m : members_)
    for (auto& p : m->parameters())
      params.push_back(p);
  optimizer_ = std::make_unique<FlatAdam>(params, FlatAdamOptions{options.lr});
  // Read after the optimizer rebinds the parameters to its flat buffer, so the views stay the live ones.
  if (options_.weight_decay > 0)
    for (const auto& [key, m] : named_dynamics(dynamics_, members_))
      for (const at::Tensor& w : weight_matrices(*m))
        decayed_.push_back(w);
}

ModelLosses ModelLearner::update(const Batch& candidates) {
  check(candidates.steps == options_.rollout_steps,
        "the model learner takes sequences of {} transitions, got {}", options_.rollout_steps,
        candidates.steps);
  if (options_.hard_mining > 1) return update_mined(candidates);
  return update_on(candidates, candidates);
}

ModelLosses ModelLearner::update_mined(const Batch& candidates) {
  const int64_t rows = candidates.states.size(0);
  check(rows % options_.hard_mining == 0, "model.hard_mining {}: a batch of {} rows is not a multiple of it",
        options_.hard_mining, rows);
  const int64_t batch = rows / options_.hard_mining;
  torch::Tensor hardest;
  double uniform_nll = 0;
  {
    c10::InferenceMode guard;
    // Per row sum_j z_j^2 with z = (s' - f(s, a)) / sigma: the rows' NLL up to the same constant.
    const torch::Tensor z =
        (candidates.next_states - dynamics_->forward(candidates.states, candidates.actions)) *
        torch::exp(-dynamics_->log_std());
    const torch::Tensor err = z.square().sum(1);
    // The logged loss is the uniform rows' NLL before the step, as an unmined learner logs it.
    const double n = static_cast<double>(z.size(1));
    uniform_nll = err.narrow(0, 0, batch).mean().item<double>() / (2.0 * n) +
                  dynamics_->log_std().mean().item<double>() + 0.5 * std::log(2.0 * M_PI);
    // The worst-predicted rows, in their drawn order (topk's order among equal errors is not specified).
    hardest = std::get<0>(std::get<1>(torch::topk(err, batch)).sort());
  }
  const Batch uniform = select_rows(candidates, torch::arange(batch, torch::kLong));
  ModelLosses losses = update_on(select_rows(candidates, hardest), uniform);
  losses.dynamics = uniform_nll;
  return losses;
}

ModelLosses ModelLearner::update_on(const Batch& b, const Batch& reward_batch) {
  ModelLosses losses;
  const int64_t batch = b.states.size(0) / b.steps;
  if (b.steps > 1) {
    // The open-loop loss backpropagates through the K predictions: autograd, outside inference mode.
    losses.dynamics =
        dynamics_->rollout_loss_with_gradient(b.states.narrow(0, 0, batch), b.actions, b.next_states);
    for (DynamicsModel& m : members_)
      losses.dynamics +=
          m->rollout_loss_with_gradient(b.states.narrow(0, 0, batch), b.actions, b.next_states);
  }
  // The other backward passes are written by hand (no autograd graph): each writes its own parameters'
  // gradients, so the flat gradient buffer needs no zeroing.
  c10::InferenceMode guard;
  if (b.steps == 1) {
    losses.dynamics = dynamics_->loss_with_gradient(b.states, b.actions, b.next_states);
    for (DynamicsModel& m : members_)
      losses.dynamics += m->loss_with_gradient(b.states, b.actions, b.next_states);
  }
  losses.dynamics /= static_cast<double>(members_.size() + 1);
  add_weight_decay(decayed_, options_.weight_decay);
  // The reward model trains on each sequence's first transition, at the one-step cost: a uniform sample
  // of the transitions that start a sequence (all but the last K - 1 of each episode).
  const Batch& r = reward_batch;
  auto first = [&](const torch::Tensor& t) { return r.steps == 1 ? t : t.narrow(0, 0, batch); };
  // r(s', a) regresses on the reached state; with gamma 0 the TD target's next terms do not count.
  const torch::Tensor& reward_state = reward_->options().reads_next_state ? r.next_states : r.states;
  losses.reward = reward_->td_loss_with_gradient(first(reward_state), first(r.actions), first(r.rewards),
                                                 first(r.next_states), first(r.next_actions), first(r.dones),
                                                 options_.reward_gamma, options_.reward_weight);
  optimizer_->step();
  // The domain grows with the data the dynamics model is fitted to (for planner.clamp_to_data).
  dynamics_->extend_domain(b.states);
  dynamics_->extend_domain(b.next_states);
  return losses;
}

void ModelLearner::save(CheckpointWriter& w) const {
  for (const auto& [key, m] : named_dynamics(dynamics_, members_))
    w.add_module(key, *m);
  w.add_module("reward", *reward_);
  save_training_state(w);
}

void ModelLearner::load(CheckpointReader& r) {
  for (auto [key, m] : named_dynamics(dynamics_, members_))
    r.load_module(key, *m);
  r.load_module("reward", *reward_);
  load_training_state(r);
}

void ModelLearner::save_training_state(CheckpointWriter& w) const {
  optimizer_->save(w, "models");
  if (dynamics_->has_domain()) {
    w.add_tensor(kDomainLow, dynamics_->domain_low());
    w.add_tensor(kDomainHigh, dynamics_->domain_high());
  }
}

void ModelLearner::load_training_state(CheckpointReader& r) {
  optimizer_->load(r, "models");
  // Checkpoints from before the domain was kept have none: it then grows again from the next batches.
  if (r.has(kDomainLow) && r.has(kDomainHigh))
    dynamics_->set_domain(r.tensor(kDomainLow), r.tensor(kDomainHigh));
}

}  // namespace hlt
