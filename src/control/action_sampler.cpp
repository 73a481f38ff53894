#include "hlt/control/action_sampler.h"

#include <cmath>

#include <torch/torch.h>

namespace hlt {

std::pair<at::Tensor, at::Tensor> PolicySampler::sample(const at::Tensor& states, const at::Tensor& plan_t,
                                                        int64_t t) {
  auto [mean, log_std] = policy_->forward(states);
  const at::Tensor u = mean + log_std.exp() * torch::randn_like(mean);
  const at::Tensor v = u.tanh();
  return {v, GaussianPolicyImpl::squashed_log_prob(u, v, mean, log_std).squeeze(-1)};
}

void FilteredNoiseSampler::begin(int64_t samples, const at::Tensor& plan) {
  eta_ = torch::zeros({samples, plan.size(1)}, plan.options());
}

std::pair<at::Tensor, at::Tensor> FilteredNoiseSampler::sample(const at::Tensor& states,
                                                               const at::Tensor& plan_t, int64_t t) {
  const at::Tensor z = torch::randn_like(eta_);
  eta_ = filter_ * eta_ + (1.0 - filter_) * sigma_ * z;
  const at::Tensor v = (plan_t.unsqueeze(0) + eta_).clamp(-1.0, 1.0);
  // log N(eps; 0, sigma^2) with eps = sigma z, summed over action dimensions.
  const double log_norm = -std::log(sigma_) - 0.5 * std::log(2.0 * M_PI);
  const at::Tensor log_p = (-0.5 * z.square() + log_norm).sum(-1);
  return {v, log_p};
}

}  // namespace hlt
