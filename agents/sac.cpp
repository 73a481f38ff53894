#include "agents/sac.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <ATen/CPUGeneratorImpl.h>
#include <torch/torch.h>

#include "hlt/core/checkpoint.h"
#include "hlt/nn/batched_forward.h"
#include "hlt/simd/vector_math.h"
#include "hlt/util/error.h"

namespace hlt {

namespace {

// The per-sample arithmetic of the actor's gradient runs as plain loops over [B, m] values (a few
// thousand), where one dispatched op per term cost more than the values' work. Each loop does, value for
// value and in the same order, the float arithmetic ATen's elementwise kernels do (scalars rounded to the
// tensor's dtype first; no fused multiply-adds: this file is built for baseline x86-64, -std=c++17), so the
// results are bit for bit those of the tensor expressions in the comments.

// The critics' TD errors td_i = Q_i(s, a) - y for q [2, B, 1], y = r + gamma (1 - done) q_next with
// q_next = min(Q'_0, Q'_1) - alpha log pi(a'|s') from the target critics' q_target [2, B, 1]; and the
// loss's gradient td * (2 / B). As the tensor expressions
//   q_next = torch::min(q_target[0], q_target[1]) - alpha_t * log_prob;
//   y = rewards + gamma * (1.0 - dones) * q_next;  td = q - y;  grad = td * (2.0 / B),
// with min's NaN propagation.
std::pair<torch::Tensor, torch::Tensor> td_errors(const torch::Tensor& q, const torch::Tensor& q_target,
                                                  const torch::Tensor& log_prob, const torch::Tensor& rewards,
                                                  const torch::Tensor& dones, double alpha, double gamma,
                                                  double batch) {
  const torch::Tensor qc = q.contiguous(), tc = q_target.contiguous(), lc = log_prob.contiguous(),
                      rc = rewards.contiguous(), dc = dones.contiguous();
  const int64_t n = rc.numel();
  check(qc.dim() == 3 && qc.size(0) == 2 && qc.numel() == 2 * n && tc.sizes() == qc.sizes() &&
            lc.numel() == n && dc.numel() == n && lc.scalar_type() == qc.scalar_type() &&
            rc.scalar_type() == qc.scalar_type() && dc.scalar_type() == qc.scalar_type(),
        "SAC's TD errors need q [2, B, 1] and [B, 1] rewards, dones and log-probabilities of its dtype");
  torch::Tensor td = at::empty_like(qc), grad = at::empty_like(qc);
  dispatch_floating(qc, [&](auto tag) {
    using scalar_t = decltype(tag);
    const scalar_t one = 1, a = static_cast<scalar_t>(alpha), g = static_cast<scalar_t>(gamma),
                   scale = static_cast<scalar_t>(2.0 / batch);
    const scalar_t *pq = qc.data_ptr<scalar_t>(), *pt = tc.data_ptr<scalar_t>(),
                   *pl = lc.data_ptr<scalar_t>(), *pr = rc.data_ptr<scalar_t>(),
                   *pd = dc.data_ptr<scalar_t>();
    scalar_t *ptd = td.data_ptr<scalar_t>(), *pg = grad.data_ptr<scalar_t>();
    for (int64_t i = 0; i < n; ++i) {
      const scalar_t t0 = pt[i], t1 = pt[n + i];
      const scalar_t min_t = t0 != t0 ? t0 : (t1 != t1 ? t1 : std::min(t0, t1));
      const scalar_t q_next = min_t - a * pl[i];
      const scalar_t y = pr[i] + g * (one - pd[i]) * q_next;
      for (int64_t c = 0; c < 2; ++c) {
        ptd[c * n + i] = pq[c * n + i] - y;
        pg[c * n + i] = ptd[c * n + i] * scale;
      }
    }
  });
  return {td, grad};
}

// d(-min Q)/dQ_i as autograd's min, for q [2, B, 1]: the smaller critic takes -1/B, ties share it (NaN
// compares unequal, so both take it):
//   g = full_like(q0, -1/B); g_tie = where(q0 == q1, g * 0.5, g);
//   stack({g_tie.masked_fill(q0 > q1, 0), g_tie.masked_fill(q0 < q1, 0)}).
torch::Tensor min_q_gradient(const torch::Tensor& q, double batch) {
  const torch::Tensor qc = q.contiguous();
  torch::Tensor grad = at::empty_like(qc);
  const int64_t n = qc.size(1) * qc.size(2);
  dispatch_floating(qc, [&](auto tag) {
    using scalar_t = decltype(tag);
    const scalar_t g = static_cast<scalar_t>(-1.0 / batch);
    const scalar_t g_tie = g * static_cast<scalar_t>(0.5);
    const scalar_t* q0 = qc.data_ptr<scalar_t>();
    const scalar_t* q1 = q0 + n;
    scalar_t* g0 = grad.data_ptr<scalar_t>();
    scalar_t* g1 = g0 + n;
    for (int64_t i = 0; i < n; ++i) {
      const scalar_t shared = q0[i] == q1[i] ? g_tie : g;
      g0[i] = q0[i] > q1[i] ? scalar_t(0) : shared;
      g1[i] = q0[i] < q1[i] ? scalar_t(0) : shared;
    }
  });
  return grad;
}

// The actor loss's gradients in the pre-tanh action u and in the raw log-std (see Sac::update):
//   oma2 = 1 - a^2;  grad_u = grad_a * oma2 + (2 alpha / B) * a * oma2 / (oma2 + kTanhEpsilon);
//   grad_log_std = (grad_u * std * eps - alpha / B).masked_fill_(raw < lo | raw > hi, 0).
std::pair<torch::Tensor, torch::Tensor> actor_gradients(const torch::Tensor& grad_a, const torch::Tensor& a,
                                                        const torch::Tensor& std, const torch::Tensor& eps,
                                                        const torch::Tensor& raw_log_std, double alpha,
                                                        double batch, double log_std_min,
                                                        double log_std_max) {
  const torch::Tensor ga = grad_a.contiguous(), ac = a.contiguous(), sc = std.contiguous(),
                      ec = eps.contiguous(), rc = raw_log_std.contiguous();
  check(ga.sizes() == ac.sizes() && sc.sizes() == ac.sizes() && ec.sizes() == ac.sizes() &&
            rc.sizes() == ac.sizes(),
        "SAC's actor gradient needs tensors of one shape");
  torch::Tensor grad_u = at::empty_like(ac), grad_log_std = at::empty_like(ac);
  dispatch_floating(ac, [&](auto tag) {
    using scalar_t = decltype(tag);
    const scalar_t one = 1, entropy_scale = static_cast<scalar_t>(2.0 * alpha / batch),
                   tanh_eps = static_cast<scalar_t>(kTanhEpsilon),
                   alpha_b = static_cast<scalar_t>(alpha / batch), lo = static_cast<scalar_t>(log_std_min),
                   hi = static_cast<scalar_t>(log_std_max);
    const scalar_t *pga = ga.data_ptr<scalar_t>(), *pa = ac.data_ptr<scalar_t>(),
                   *ps = sc.data_ptr<scalar_t>(), *pe = ec.data_ptr<scalar_t>(),
                   *pr = rc.data_ptr<scalar_t>();
    scalar_t *pu = grad_u.data_ptr<scalar_t>(), *pl = grad_log_std.data_ptr<scalar_t>();
    for (int64_t i = 0; i < ac.numel(); ++i) {
      const scalar_t a2 = pa[i] * pa[i];
      const scalar_t oma2 = one - a2;
      const scalar_t entropy = entropy_scale * pa[i] * oma2 / (oma2 + tanh_eps);
      pu[i] = pga[i] * oma2 + entropy;
      const bool clamped = pr[i] < lo || pr[i] > hi;
      pl[i] = clamped ? scalar_t(0) : pu[i] * ps[i] * pe[i] - alpha_b;
    }
  });
  return {grad_u, grad_log_std};
}

}  // namespace

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
  // Every gradient below is written by hand. InferenceMode rather than NoGradGuard: it also skips the
  // version-counter and view bookkeeping of each of the update's ~150 dispatched ops (4 % of an update).
  c10::InferenceMode guard;
  SacLosses out;
  const torch::Tensor alpha_t = log_alpha_.detach().exp();
  const double alpha = alpha_t.item<double>();
  const double batch = static_cast<double>(b.states.size(0));

  // Critics: r + gamma (1 - done) (min Q'(s', a') - alpha log pi(a'|s')), a' ~ pi(.|s').
  PolicySample next = policy_->rsample(b.next_states, generator_);
  // forward_keep rather than min_q: the same arithmetic into the target critics' own buffers, which no
  // backward pass ever reads.
  const torch::Tensor& q_target = critics_target_->forward_keep(b.next_states, next.action);
  // The loss is the sum of the two critics' mean squared TD errors; its gradient in Q_i is 2 (Q_i - y) / B.
  auto [td, grad_td] = td_errors(critics_->forward_keep(b.states, b.actions), q_target, next.log_prob,
                                 b.rewards, b.dones, alpha, options_.gamma, batch);
  const double critic_loss = td.square().mean().item<double>() * 2.0;
  critics_->backward_parameters(grad_td);
  q_opt_->step();

  // Policy: minimise E[alpha log pi(a|s) - min Q(s, a)] with a = tanh(u), u = mu + sigma eps
  // reparameterised. With log pi = sum_j [-eps_j^2 / 2 - log sigma_j - log(2 pi) / 2 - log(1 - a_j^2 + c)],
  // the gradients are, per sample and action dimension (1/B from the mean):
  //   dL/du = (1 - a^2) dL/da + alpha 2 a (1 - a^2) / (1 - a^2 + c),  dL/da = -dminQ/da / B,
  //   dL/dmu = dL/du,  dL/dlog_sigma = dL/du sigma eps - alpha / B  (zero where the clamp is active);
  // eps's own terms cancel, since u - mu = sigma eps does not depend on mu or sigma once eps is drawn.
  const auto& opt = policy_->options();
  // The heads see the states as the policy normalises them (the actor's gradient is taken with respect to
  // the parameters and the action, never the state, so normalising first is exact).
  const torch::Tensor policy_input = policy_->normalize(b.states);
  const torch::Tensor mean = mean_pass_.forward(policy_input);
  const torch::Tensor raw_log_std = log_std_pass_.forward(policy_input);
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
  const torch::Tensor grad_a = critics_->backward_action(min_q_gradient(q, batch));
  auto [grad_u, grad_log_std] =
      actor_gradients(grad_a, a, std, eps, raw_log_std, alpha, batch, opt.log_std_min, opt.log_std_max);
  if (options_.bc_weight > 0) {
    // bc_weight E[-log pi(a_b|s)] with u_b = atanh(clip(a_b)), z = (u_b - mu) / sigma:
    //   dL/dmu = -w z / (sigma B),  dL/dlog_sigma = w (1 - z^2) / B (zero where the clamp is active);
    // the tanh correction does not depend on the policy.
    const torch::Tensor target_a = b.actions.clamp(-kBcActionClip, kBcActionClip);
    const torch::Tensor target_u = torch::atanh(target_a);
    const torch::Tensor z = (target_u - mean) / std;
    const double w = options_.bc_weight / batch;
    grad_u.add_(z / std, -w);
    const torch::Tensor clamped = (raw_log_std < opt.log_std_min).logical_or_(raw_log_std > opt.log_std_max);
    grad_log_std.add_((1.0 - z.square()).masked_fill_(clamped, 0.0), w);
    out.bc = -GaussianPolicyImpl::squashed_log_prob(target_u, target_a, mean, log_std).mean().item<double>();
  }
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
