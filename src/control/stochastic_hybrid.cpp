#include "hlt/control/stochastic_hybrid.h"

#include <torch/torch.h>

#include "hlt/util/error.h"

namespace hlt {

StochasticHybrid::StochasticHybrid(std::shared_ptr<ActionSampler> sampler, DynamicsModel dynamics,
                                   RewardModel reward, const StochasticHybridOptions& options,
                                   GaussianPolicy fallback_policy, std::string name)
    : Controller(std::move(fallback_policy)),
      sampler_(std::move(sampler)),
      dynamics_(std::move(dynamics)),
      reward_(std::move(reward)),
      options_(options),
      name_(std::move(name)) {
  check(sampler_ != nullptr, "{}: needs an action sampler", name_);
  check(options.horizon >= 1 && options.samples >= 1, "{}: horizon and samples must be >= 1", name_);
  check(options.lambda > 0, "{}: lambda must be > 0, got {}", name_, options.lambda);
  reset();
}

void StochasticHybrid::reset() {
  const auto& p = dynamics_->fc1->weight;
  plan_ = torch::zeros({options_.horizon, dynamics_->options().action_dim}, p.options().requires_grad(false));
}

at::Tensor StochasticHybrid::compute_action(const at::Tensor& state) {
  torch::InferenceMode guard;
  const int64_t H = options_.horizon, K = options_.samples, m = plan_.size(1);
  // Warm start: the previous plan moved one step earlier, a zero action appended.
  plan_ = torch::cat({plan_.narrow(0, 1, H - 1), torch::zeros({1, m}, plan_.options())});

  at::Tensor s = state.to(plan_.scalar_type()).unsqueeze(0).expand({K, state.size(0)});
  sampler_->begin(K, plan_);
  std::vector<at::Tensor> actions, rewards, log_p;
  actions.reserve(H);
  rewards.reserve(H);
  log_p.reserve(H);
  for (int64_t t = 0; t < H; ++t) {
    auto [v, lp] = sampler_->sample(s, plan_[t], t);
    rewards.push_back(reward_->forward(s, v).squeeze(-1));
    s = dynamics_->forward(s, v);
    actions.push_back(v);
    log_p.push_back(lp);
  }
  // J_t^k: predicted reward to go from step t, [H, K].
  const at::Tensor J = torch::stack(rewards).flip(0).cumsum(0).flip(0);
  samples_ = torch::stack(actions);
  log_density_ = torch::stack(log_p);
  at::Tensor log_w = J / options_.lambda;
  if (options_.density_in_weights) log_w = log_w + log_density_;
  // Normalise in log space: subtracting the per-step max keeps exp() in range.
  at::Tensor w = (log_w - std::get<0>(log_w.max(1, /*keepdim=*/true))).exp() + options_.weight_floor;
  w = w / w.sum(1, /*keepdim=*/true);
  // a_t += sum_k w_t^k (v_t^k - a_t), for all t at once: [H, 1, K] x [H, K, m].
  const at::Tensor da = samples_ - plan_.unsqueeze(1);
  plan_ = plan_ + torch::bmm(w.unsqueeze(1), da).squeeze(1);
  weights_ = w;
  at::Tensor action = plan_[0].clone();
  if (!torch::isfinite(plan_).all().item<bool>()) {
    // Do not carry a poisoned plan into the next step; the base class substitutes the fallback action.
    plan_.zero_();
  }
  return action;
}

}  // namespace hlt
