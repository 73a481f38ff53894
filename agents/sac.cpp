#include "agents/sac.h"

#include <cmath>

#include <ATen/CPUGeneratorImpl.h>
#include <torch/torch.h>

#include "hlt/core/checkpoint.h"
#include "hlt/simd/vector_math.h"
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
  mean_pass_ = DenseStack(policy_->mean_layers, policy_->options().mean_activation);
  log_std_pass_ = DenseStack(policy_->log_std_layers, Activation::kRelu);
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
  torch::NoGradGuard no_grad;  // every gradient below is written by hand
  SacLosses out;
  const torch::Tensor alpha_t = log_alpha_.detach().exp();
  const double alpha = alpha_t.item<double>();
  const double batch = static_cast<double>(b.states.size(0));

  // Critics: r + gamma (1 - done) (min Q'(s', a') - alpha log pi(a'|s')), a' ~ pi(.|s').
  PolicySample next = policy_->rsample(b.next_states, generator_);
  const torch::Tensor q_next = critics_target_->min_q(b.next_states, next.action) - alpha_t * next.log_prob;
  const torch::Tensor target = b.rewards + options_.gamma * (1.0 - b.dones) * q_next;
  // The loss is the sum of the two critics' mean squared TD errors; its gradient in Q_i is 2 (Q_i - y) / B.
  const torch::Tensor td = critics_->forward_keep(b.states, b.actions) - target;
  const double critic_loss = td.square().mean().item<double>() * 2.0;
  critics_->backward_parameters(td * (2.0 / batch));
  q_opt_->step();

  // Policy: minimise E[alpha log pi(a|s) - min Q(s, a)] with a = tanh(u), u = mu + sigma eps
  // reparameterised. With log pi = sum_j [-eps_j^2 / 2 - log sigma_j - log(2 pi) / 2 - log(1 - a_j^2 + c)],
  // the gradients are, per sample and action dimension (1/B from the mean):
  //   dL/du = (1 - a^2) dL/da + alpha 2 a (1 - a^2) / (1 - a^2 + c),  dL/da = -dminQ/da / B,
  //   dL/dmu = dL/du,  dL/dlog_sigma = dL/du sigma eps - alpha / B  (zero where the clamp is active);
  // eps's own terms cancel, since u - mu = sigma eps does not depend on mu or sigma once eps is drawn.
  const auto& opt = policy_->options();
  const torch::Tensor mean = mean_pass_.forward(b.states);
  const torch::Tensor raw_log_std = log_std_pass_.forward(b.states);
  const torch::Tensor log_std = raw_log_std.clamp(opt.log_std_min, opt.log_std_max);
  const torch::Tensor std = log_std.exp();
  const torch::Tensor eps = at::randn(mean.sizes(), generator_, mean.options());
  const torch::Tensor u = mean + std * eps;
  const torch::Tensor a = torch::tanh(u);
  const torch::Tensor log_prob = GaussianPolicyImpl::squashed_log_prob(u, a, mean, log_std);
  const torch::Tensor q = critics_->forward_keep(b.states, a);
  const torch::Tensor q0 = q[0], q1 = q[1];
  const torch::Tensor min_q = torch::min(q0, q1);
  const double actor_loss = (alpha_t * log_prob - min_q).mean().item<double>();
  // d(-min Q)/dQ_i as autograd's min: the smaller critic takes the gradient, ties share it.
  const torch::Tensor g = torch::full_like(q0, -1.0 / batch);
  const torch::Tensor tie = q0 == q1;
  const torch::Tensor g_tie = torch::where(tie, g * 0.5, g);
  const torch::Tensor grad_q =
      torch::stack({g_tie.masked_fill(q0 > q1, 0.0), g_tie.masked_fill(q0 < q1, 0.0)});
  const torch::Tensor grad_a = critics_->backward_action(grad_q);
  const torch::Tensor one_minus_a2 = 1.0 - a.square();
  torch::Tensor grad_u =
      grad_a * one_minus_a2 + (2.0 * alpha / batch) * a * one_minus_a2 / (one_minus_a2 + kTanhEpsilon);
  torch::Tensor grad_log_std =
      (grad_u * std * eps - alpha / batch)
          .masked_fill_((raw_log_std < opt.log_std_min).logical_or(raw_log_std > opt.log_std_max), 0.0);
  mean_pass_.backward(grad_u);
  log_std_pass_.backward(grad_log_std);
  policy_opt_->step();

  // Temperature: minimise E[-log_alpha (log pi + target_entropy)], whose gradient in log_alpha is
  // -(E[log pi] + target_entropy): written directly instead of a backward pass through one product.
  const double mean_log_prob = log_prob.mean().item<double>();
  alpha_opt_->flat_gradients().fill_(-(mean_log_prob + target_entropy_));
  alpha_opt_->step();

  // Polyak averaging of the target critics: one pass over the flat buffers (ATen's lerp_ is a scalar loop,
  // 5 % of an update; hlt's vector pass does its arithmetic).
  const at::Tensor& online = q_opt_->flat_parameters();
  if (target_flat_.scalar_type() == at::kFloat && target_flat_.is_contiguous() && online.is_contiguous()) {
    lerp(target_flat_.data_ptr<float>(), online.data_ptr<float>(), static_cast<float>(options_.tau),
         target_flat_.numel());
  } else {
    target_flat_.lerp_(online, options_.tau);
  }

  out.critic = 0.5 * critic_loss;
  out.actor = actor_loss;
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
