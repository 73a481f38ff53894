#include "agents/sac.h"

#include <cmath>

#include <ATen/CPUGeneratorImpl.h>
#include <torch/torch.h>

#include "hlt/core/checkpoint.h"
#include "hlt/util/error.h"

namespace hlt {

Sac::Sac(GaussianPolicy policy, int64_t state_dim, int64_t action_dim, const SacOptions& options)
    : options_(options), policy_(std::move(policy)) {
  target_entropy_ =
      std::isnan(options.target_entropy) ? -static_cast<double>(action_dim) : options.target_entropy;
  const TwinQNetworkOptions qo{state_dim, action_dim, options.q_hidden};
  critics_ = TwinQNetwork(qo);
  critics_target_ = TwinQNetwork(qo);
  log_alpha_ = torch::full({1}, std::log(options.initial_alpha)).requires_grad_(true);
  q_opt_ = std::make_unique<FlatAdam>(critics_->parameters(), FlatAdamOptions{options.q_lr});
  policy_opt_ = std::make_unique<FlatAdam>(policy_->parameters(), FlatAdamOptions{options.policy_lr});
  alpha_opt_ =
      std::make_unique<FlatAdam>(std::vector<torch::Tensor>{log_alpha_}, FlatAdamOptions{options.alpha_lr});
  generator_ = at::make_generator<at::CPUGeneratorImpl>(options.seed);
  // The target critics start as copies and are only ever averaged, never trained.
  target_flat_ = flatten_parameters(critics_target_->parameters());
  torch::NoGradGuard no_grad;
  target_flat_.copy_(q_opt_->flat_parameters());
  for (auto& p : critics_target_->parameters())
    p.requires_grad_(false);
}

double Sac::alpha() const {
  return std::exp(log_alpha_.item<double>());
}

SacLosses Sac::update(const Batch& b) {
  SacLosses out;
  const torch::Tensor alpha = log_alpha_.detach().exp();

  // Critics: r + gamma (1 - done) (min Q'(s', a') - alpha log pi(a'|s')), a' ~ pi(.|s').
  torch::Tensor target;
  {
    torch::NoGradGuard no_grad;
    PolicySample next = policy_->rsample(b.next_states, generator_);
    torch::Tensor q_next = critics_target_->min_q(b.next_states, next.action) - alpha * next.log_prob;
    target = b.rewards + options_.gamma * (1.0 - b.dones) * q_next;
  }
  // The sum of the two critics' mean squared TD errors.
  torch::Tensor critic_loss = (critics_->forward(b.states, b.actions) - target).square().mean() * 2.0;
  q_opt_->zero_grad();
  critic_loss.backward();
  q_opt_->step();

  // Policy: minimise E[alpha log pi(a|s) - min Q(s, a)] with a reparameterised; the critics' own weight
  // gradients are not needed here, so they are switched off for this pass.
  const auto critic_params = critics_->parameters();
  for (auto& p : critic_params)
    p.requires_grad_(false);
  PolicySample fresh = policy_->rsample(b.states, generator_);
  torch::Tensor actor_loss = (alpha * fresh.log_prob - critics_->min_q(b.states, fresh.action)).mean();
  policy_opt_->zero_grad();
  actor_loss.backward();
  policy_opt_->step();
  for (auto& p : critic_params)
    p.requires_grad_(true);

  // Temperature: minimise E[-log_alpha (log pi + target_entropy)], whose gradient in log_alpha is
  // -(E[log pi] + target_entropy): written directly instead of a backward pass through one product.
  const double mean_log_prob = fresh.log_prob.detach().mean().item<double>();
  alpha_opt_->flat_gradients().fill_(-(mean_log_prob + target_entropy_));
  alpha_opt_->step();

  // Polyak averaging of the target critics: one pass over the flat buffers.
  {
    torch::NoGradGuard no_grad;
    target_flat_.lerp_(q_opt_->flat_parameters(), options_.tau);
  }

  out.critic = 0.5 * critic_loss.item<double>();
  out.actor = actor_loss.item<double>();
  out.alpha = Sac::alpha();
  out.entropy = -mean_log_prob;
  return out;
}

void Sac::save(CheckpointWriter& w) const {
  w.add_module("policy", *policy_);
  save_training_state(w);
}

void Sac::load(CheckpointReader& r) {
  r.load_module("policy", *policy_);
  load_training_state(r);
}

void Sac::save_training_state(CheckpointWriter& w) const {
  w.add_module("critics", *critics_);
  w.add_module("critics_target", *critics_target_);
  w.add_tensor("log_alpha", log_alpha_.detach());
  w.add_tensor("sac_rng", generator_.get_state());
  q_opt_->save(w, "q");
  policy_opt_->save(w, "policy");
  alpha_opt_->save(w, "alpha");
}

void Sac::load_training_state(CheckpointReader& r) {
  r.load_module("critics", *critics_);
  r.load_module("critics_target", *critics_target_);
  torch::Tensor la = r.tensor("log_alpha");
  check(la.sizes() == log_alpha_.sizes(), "checkpoint {}: log_alpha has the wrong shape", r.path());
  {
    torch::NoGradGuard no_grad;
    log_alpha_.copy_(la);
  }
  generator_.set_state(r.tensor("sac_rng"));
  q_opt_->load(r, "q");
  policy_opt_->load(r, "policy");
  alpha_opt_->load(r, "alpha");
}

}  // namespace hlt
