// Action samplers: the distribution the stochastic planner draws its K rollouts' actions from. The hybrid
// controller samples from the policy; NN-MPPI samples low-pass-filtered Gaussian noise around the plan. Both
// return each sample's log-density, which enters the planner's weights.
#pragma once

#include <cstdint>
#include <utility>

#include <ATen/core/Tensor.h>

#include "hlt/nn/gaussian_policy.h"

namespace hlt {

class ActionSampler {
 public:
  virtual ~ActionSampler() = default;
  // Called once per planning call before step 0, with the plan [H, m].
  virtual void begin(int64_t samples, const at::Tensor& plan) {}
  // Actions v [K, m] in [-1, 1] for step t from the rollouts' states [K, n] and the plan entry a_t [m], and
  // their log-densities [K].
  virtual std::pair<at::Tensor, at::Tensor> sample(const at::Tensor& states, const at::Tensor& plan_t,
                                                   int64_t t) = 0;
};

// v ~ pi(.|s) at every rollout's own state (closed loop); log-density with the tanh correction.
class PolicySampler : public ActionSampler {
 public:
  explicit PolicySampler(GaussianPolicy policy) : policy_(std::move(policy)) {}
  std::pair<at::Tensor, at::Tensor> sample(const at::Tensor& states, const at::Tensor& plan_t,
                                           int64_t t) override;
  const GaussianPolicy& policy() const { return policy_; }

 private:
  GaussianPolicy policy_;
};

// NN-MPPI's noise: eps_t ~ N(0, sigma^2), eta_t = filter * eta_{t-1} + (1 - filter) * eps_t, v = clip(a_t +
// eta_t); log-density of eps_t under N(0, sigma^2).
class FilteredNoiseSampler : public ActionSampler {
 public:
  FilteredNoiseSampler(double sigma, double filter) : sigma_(sigma), filter_(filter) {}
  void begin(int64_t samples, const at::Tensor& plan) override;
  std::pair<at::Tensor, at::Tensor> sample(const at::Tensor& states, const at::Tensor& plan_t,
                                           int64_t t) override;

 private:
  double sigma_, filter_;
  at::Tensor eta_;
};

}  // namespace hlt
