#include "agents/sac.h"

#include <cmath>

#include <torch/torch.h>

#include "hlt/core/checkpoint.h"
#include "hlt/util/error.h"

namespace hlt {

Sac::Sac(GaussianPolicy policy, int64_t state_dim, int64_t action_dim, const SacOptions& options)
    : options_(options), policy_(std::move(policy)) {
  target_entropy_ =
      std::isnan(options.target_entropy) ? -static_cast<double>(action_dim) : options.target_entropy;
  const QNetworkOptions qo{state_dim, action_dim, options.q_hidden};
  q1_ = QNetwork(qo);
  q2_ = QNetwork(qo);
  q1_target_ = QNetwork(qo);
  q2_target_ = QNetwork(qo);
  torch::NoGradGuard no_grad;
  for (auto* q : {&q1_, &q2_}) {
    for (auto& p : (*q)->parameters())
      q_params_.push_back(p);
  }
  for (auto* q : {&q1_target_, &q2_target_}) {
    for (auto& p : (*q)->parameters()) {
      p.requires_grad_(false);
      target_params_.push_back(p);
    }
  }
  for (size_t i = 0; i < q_params_.size(); ++i)
    target_params_[i].copy_(q_params_[i]);
  log_alpha_ = torch::full({1}, std::log(options.initial_alpha)).requires_grad_(true);
  q_opt_ = std::make_unique<torch::optim::Adam>(q_params_, torch::optim::AdamOptions(options.q_lr));
  policy_opt_ = std::make_unique<torch::optim::Adam>(policy_->parameters(),
                                                     torch::optim::AdamOptions(options.policy_lr));
  alpha_opt_ = std::make_unique<torch::optim::Adam>(std::vector<torch::Tensor>{log_alpha_},
                                                    torch::optim::AdamOptions(options.alpha_lr));
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
    PolicySample next = policy_->rsample(b.next_states);
    torch::Tensor q_next = torch::min(q1_target_->forward(b.next_states, next.action),
                                      q2_target_->forward(b.next_states, next.action)) -
                           alpha * next.log_prob;
    target = b.rewards + options_.gamma * (1.0 - b.dones) * q_next;
  }
  torch::Tensor critic_loss = (q1_->forward(b.states, b.actions) - target).square().mean() +
                              (q2_->forward(b.states, b.actions) - target).square().mean();
  q_opt_->zero_grad();
  critic_loss.backward();
  q_opt_->step();

  // Policy: minimise E[alpha log pi(a|s) - min Q(s, a)] with a reparameterised; the critics' own weight
  // gradients are not needed here, so they are switched off for this pass.
  for (auto& p : q_params_)
    p.requires_grad_(false);
  PolicySample fresh = policy_->rsample(b.states);
  torch::Tensor q_new =
      torch::min(q1_->forward(b.states, fresh.action), q2_->forward(b.states, fresh.action));
  torch::Tensor actor_loss = (alpha * fresh.log_prob - q_new).mean();
  policy_opt_->zero_grad();
  actor_loss.backward();
  policy_opt_->step();
  for (auto& p : q_params_)
    p.requires_grad_(true);

  // Temperature: minimise E[-log_alpha (log pi + target_entropy)].
  torch::Tensor log_prob = fresh.log_prob.detach();
  torch::Tensor alpha_loss = -(log_alpha_ * (log_prob + target_entropy_)).mean();
  alpha_opt_->zero_grad();
  alpha_loss.backward();
  alpha_opt_->step();

  // Polyak averaging of the target critics, one fused op per parameter.
  {
    torch::NoGradGuard no_grad;
    for (size_t i = 0; i < q_params_.size(); ++i)
      target_params_[i].lerp_(q_params_[i], options_.tau);
  }

  out.critic = 0.5 * critic_loss.item<double>();
  out.actor = actor_loss.item<double>();
  out.alpha = Sac::alpha();
  out.entropy = -log_prob.mean().item<double>();
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
  w.add_module("q1", *q1_);
  w.add_module("q2", *q2_);
  w.add_module("q1_target", *q1_target_);
  w.add_module("q2_target", *q2_target_);
  w.add_tensor("log_alpha", log_alpha_.detach());
  w.add_optimizer("q", *q_opt_);
  w.add_optimizer("policy", *policy_opt_);
  w.add_optimizer("alpha", *alpha_opt_);
}

void Sac::load_training_state(CheckpointReader& r) {
  r.load_module("q1", *q1_);
  r.load_module("q2", *q2_);
  r.load_module("q1_target", *q1_target_);
  r.load_module("q2_target", *q2_target_);
  torch::Tensor la = r.tensor("log_alpha");
  check(la.sizes() == log_alpha_.sizes(), "checkpoint {}: log_alpha has the wrong shape", r.path());
  {
    torch::NoGradGuard no_grad;
    log_alpha_.copy_(la);
  }
  r.load_optimizer("q", *q_opt_);
  r.load_optimizer("policy", *policy_opt_);
  r.load_optimizer("alpha", *alpha_opt_);
}

}  // namespace hlt
