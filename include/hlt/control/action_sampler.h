// Action samplers: the distribution the stochastic planner draws its K rollouts' actions from. The hybrid
// controller samples from the policy; NN-MPPI samples low-pass-filtered Gaussian noise around the plan. Both
// report each sample's log-density, which enters the planner's weights.
//
// A planning call is begin(), then sample() once per step for all K rollouts at once, then log_density().
// Random numbers for the whole call are drawn in begin() (one tensor op), so the per-step work is a few
// batched products and Eigen array expressions. Batches are sample-major (one row per rollout), as in
// hlt/nn/batched_forward.h.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>

#include <ATen/core/Tensor.h>

#include "hlt/nn/batched_forward.h"
#include "hlt/nn/gaussian_policy.h"

namespace hlt {

// u = atanh(v) of squashed actions v (an Eigen array expression), with v clipped to +-(1 - 1e-6) first so
// that an action at +-1 (an NN-MPPI sample clipped to the bounds) maps to a finite 7.25, not infinity.
template <typename Derived>
auto clipped_atanh(const Eigen::ArrayBase<Derived>& v) {
  using T = typename Derived::Scalar;
  const T edge = T(1) - T(1e-6);
  const auto c = v.max(-edge).min(edge);
  // atanh(c) = log((1 + c) / (1 - c)) / 2
  return T(0.5) * ((T(1) + c) / (T(1) - c)).log();
}

class ActionSampler {
 public:
  virtual ~ActionSampler() = default;
  // Starts a planning call with K samples around the plan [H, m].
  virtual void begin(int64_t samples, const at::Tensor& plan) = 0;
  // Writes step t's actions [K, m] (in [-1, 1]) into `actions` from the rollouts' states [K, n] and the plan
  // entry a_t [m]. Tensors have contiguous rows and the plan's dtype.
  virtual void sample(int64_t t, const at::Tensor& states, const at::Tensor& plan_t, at::Tensor& actions) = 0;
  // Log-densities [H, K] of the actions [H, K, m] drawn since begin().
  virtual at::Tensor log_density(const at::Tensor& actions) = 0;
};

// v = tanh(u), u ~ N(mu(s), Sigma(s)) at every rollout's own state (closed loop). The reported log-density
// is that of the Gaussian pi = N(mu, Sigma) the paper's Theorem 2 weights with (the authors' code too), at
// the pre-tanh sample u; with `tanh_correction` it is the density of the squashed action v instead, which
// adds -log(1 - v^2 + 1e-6) per dimension: up to +13.8 for a saturated action, so that a weight exp(J /
// lambda) p(v) then prefers saturated samples whatever their predicted return. With `mean_rollout` the
// first rollout follows the policy's mean (u = mu(s), eps = 0) instead of a draw: the planner's weights,
// which fall on one or two samples, can then pick the policy's own action, not only noisy versions of it.
class PolicySampler : public ActionSampler {
 public:
  explicit PolicySampler(GaussianPolicy policy, bool tanh_correction = true, bool mean_rollout = false);
  void begin(int64_t samples, const at::Tensor& plan) override;
  void sample(int64_t t, const at::Tensor& states, const at::Tensor& plan_t, at::Tensor& actions) override;
  at::Tensor log_density(const at::Tensor& actions) override;

 private:
  PolicyForward forward_;
  bool tanh_correction_, mean_rollout_;
  at::Tensor eps_, log_std_;  // [H, K, m]: standard normal draws and the log-std each was scaled by
};

// NN-MPPI's noise: z_t ~ N(0, 1), eta_t = filter * eta_{t-1} + (1 - filter) * sigma * z_t,
// v = clip(a_t + eta_t, -1, 1); log-density of sigma z_t under N(0, sigma^2).
// Given a policy (`scale`), sigma is per sample, step and action dimension: min(sigma, exp(log_std(s))) of
// the policy at the sample's own rollout state, so the samples search around the plan no wider than the
// policy is unsure there (a hybrid's plan samples: wide while SAC's policy is broad, narrow once it is
// confident, where a learned model's errors off the data would otherwise decide the action).
class FilteredNoiseSampler : public ActionSampler {
 public:
  FilteredNoiseSampler(double sigma, double filter, std::optional<GaussianPolicy> scale = std::nullopt);
  void begin(int64_t samples, const at::Tensor& plan) override;
  void sample(int64_t t, const at::Tensor& states, const at::Tensor& plan_t, at::Tensor& actions) override;
  at::Tensor log_density(const at::Tensor& actions) override;

 private:
  double sigma_, filter_;
  std::optional<PolicyForward> scale_;
  at::Tensor z_, eta_;
  at::Tensor sigmas_;  // [H, K, m] with a scale policy: each step's sigma
};

// Two proposals side by side: the first K - second_samples rollouts draw from `first` (the policy), the last
// `second_samples` from `second` (NN-MPPI's noise around the warm-started plan). Every sample, whichever
// proposal drew it, is scored by the same p(v) = pi(v | s_t) of `prior` (the policy) at the sample's own
// rollout state: the Gaussian N(mu, Sigma) at u = atanh(v) (v clipped to +-(1 - 1e-6)), with the tanh
// correction if asked for. In the weights exp(J / lambda) p(v) this is Theorem 2's bound that ties the plan
// to the policy: a plan sample far from a confident policy needs a much higher predicted return to win,
// while under a broad (or poor, uncertain) policy the models decide. With the policy first this lets the
// models keep and improve a plan of their own (the policy sampler alone ignores the warm start:
// a + sum w (v - a) = sum w v). The prior is evaluated only when log_density() is asked for, on every
// step's rollout states at once.
class MixtureSampler : public ActionSampler {
 public:
  MixtureSampler(std::shared_ptr<ActionSampler> first, std::shared_ptr<ActionSampler> second,
                 int64_t second_samples, GaussianPolicy prior, bool tanh_correction = false);
  void begin(int64_t samples, const at::Tensor& plan) override;
  void sample(int64_t t, const at::Tensor& states, const at::Tensor& plan_t, at::Tensor& actions) override;
  at::Tensor log_density(const at::Tensor& actions) override;

 private:
  std::shared_ptr<ActionSampler> first_, second_;
  int64_t second_samples_, first_samples_ = 0, horizon_ = 0;
  PolicyForward prior_;
  bool tanh_correction_;
  at::Tensor actions_first_, actions_second_;  // [K1, m], [K2, m]
  at::Tensor states_;                          // [H K, n]: every step's rollout states
};

}  // namespace hlt
