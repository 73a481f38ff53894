#include "agents/behaviour_cloning.h"

#include <torch/torch.h>

#include "hlt/core/checkpoint.h"
#include "hlt/util/error.h"

namespace hlt {

BehaviourCloning::BehaviourCloning(GaussianPolicy policy, const BehaviourCloningOptions& options)
    : policy_(std::move(policy)), options_(options) {
  check(options.weight_decay >= 0 && options.input_noise >= 0,
        "behaviour cloning's weight decay and input noise must be >= 0");
  optimizer_ = std::make_unique<FlatAdam>(policy_->parameters(), FlatAdamOptions{options.lr});
  // Read after the optimizer rebinds the parameters to its flat buffer, so the views stay the live ones.
  if (options.weight_decay > 0) decayed_ = weight_matrices(*policy_);
}

at::Tensor BehaviourCloning::nll(const at::Tensor& states, const at::Tensor& actions) {
  check(states.dim() == 2 && actions.dim() == 2 && states.size(0) == actions.size(0) && states.size(0) > 0,
        "behaviour cloning needs [B, n] states and [B, m] actions");
  const auto [mean, log_std] = policy_->forward_for_fit(states);
  const at::Tensor a = actions.clamp(-1.0 + kTanhEpsilon, 1.0 - kTanhEpsilon);
  const at::Tensor u = torch::atanh(a);
  if (!options_.censor_saturated) return -GaussianPolicyImpl::squashed_log_prob(u, a, mean, log_std).mean();
  const at::Tensor saturated = actions.abs() >= kSaturatedAt;
  const at::Tensor z = (u - mean) * torch::exp(-log_std);
  const at::Tensor density =
      -0.5 * z.square() - log_std - 0.5 * std::log(2.0 * M_PI) - torch::log(1.0 - a.square() + kTanhEpsilon);
  // At +1: P(u >= c) = Phi((mu - c) / sigma); at -1: P(u <= -c) = Phi((-c - mu) / sigma).
  const at::Tensor sign = torch::sign(actions);
  const at::Tensor tail =
      torch::special::log_ndtr((sign * mean - std::atanh(kCensorLevel)) * torch::exp(-log_std));
  return -torch::where(saturated, tail, density).sum(-1).mean();
}

double BehaviourCloning::loss(const at::Tensor& states, const at::Tensor& actions) {
  torch::NoGradGuard no_grad;
  return nll(states, actions).item<double>();
}

double BehaviourCloning::update(const at::Tensor& states, const at::Tensor& actions) {
  at::Tensor inputs = states;
  if (options_.input_noise > 0 && states.size(0) > 1)
    inputs = states + options_.input_noise * states.std(0, /*unbiased=*/true, /*keepdim=*/true) *
                          torch::randn_like(states);
  const at::Tensor l = nll(inputs, actions);
  optimizer_->zero_grad();
  l.backward();
  add_weight_decay(decayed_, options_.weight_decay);
  optimizer_->step();
  return l.item<double>();
}

void BehaviourCloning::save_training_state(CheckpointWriter& w) const {
  optimizer_->save(w, "bc");
}

void BehaviourCloning::load_training_state(CheckpointReader& r) {
  optimizer_->load(r, "bc");
}

}  // namespace hlt
