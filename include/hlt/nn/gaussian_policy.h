// hlt::GaussianPolicy: pi(a|s) = tanh(N(mu(s), diag(std(s))^2)), the paper's policy. The mean head is an MLP
// with sin (or ReLU) hidden layers, the log-std head an MLP with ReLU hidden layers clamped to [-5, 2]; the
// last layers start at U(-3e-3, 3e-3). Log-probabilities include the tanh change of variables,
// log(1 - a^2 + 1e-6) per action dimension.
#pragma once

#include <cstdint>
#include <vector>

#include <torch/nn/module.h>
#include <torch/nn/modules/container/modulelist.h>
#include <torch/nn/modules/linear.h>

#include "hlt/nn/activation.h"
#include "hlt/nn/dense_chain.h"
#include "hlt/nn/input_normalisation.h"

namespace hlt {

// The constant in the tanh correction log(1 - a^2 + kTanhEpsilon), which keeps it finite at |a| = 1.
inline constexpr double kTanhEpsilon = 1e-6;

// clamp(raw, lo, hi) whose gradient passes where the clamp is active only if a descent step would move raw
// back towards [lo, hi] (above hi: a positive gradient; below lo: a negative one); inside, the plain clamp's.
// A head past a bound returns when its loss wants it back, and stays where the loss wants it further out
// (a censored action's likelihood grows with the spread) without being pushed in.
torch::Tensor clamp_with_inward_gradient(const torch::Tensor& raw, double lo, double hi);

struct GaussianPolicyOptions {
  int64_t state_dim = 0;
  int64_t action_dim = 0;
  std::vector<int64_t> hidden = {128};
  Activation mean_activation = Activation::kSin;
  double log_std_min = -5.0;
  double log_std_max = 2.0;
  double init_scale = 3e-3;
  // Input normalisation (both empty: none): the heads see (s - input_offset) / input_scale, each of
  // state_dim entries, scales > 0. A fixed part of the function, like the activation: every way of
  // evaluating the policy applies it (forward, mean_chain, PolicyForward, SAC's hand-written pass).
  std::vector<double> input_offset, input_scale;
  // Optional, with the normalisation (empty: none): component i is seen relative to component
  // input_reference[i] (-1: to nothing), s_i - s_r before the offset and scale, r != i; references read the
  // raw state. A block's position relative to the gripper, say, shown at the millimetres that matter.
  std::vector<int64_t> input_reference;
};

struct PolicySample {
  torch::Tensor action;    // tanh(u), [B, m]
  torch::Tensor log_prob;  // [B, 1]
  torch::Tensor pre_tanh;  // u, [B, m]
};

class GaussianPolicyImpl : public torch::nn::Module {
 public:
  explicit GaussianPolicyImpl(const GaussianPolicyOptions& options);

  // The Gaussian's mean and clamped log-std before the tanh, each [B, m].
  std::pair<torch::Tensor, torch::Tensor> forward(const torch::Tensor& state);
  // forward's values for fits by likelihood (behaviour cloning); the log-std is clamped by
  // clamp_with_inward_gradient. Why: the plain clamp has no gradient outside its bounds, so one step that
  // takes the head past a bound for every state would leave it there for good (stuck at the upper bound on
  // 3 of 5 Ant seeds; docs/RESULTS.md).
  std::pair<torch::Tensor, torch::Tensor> forward_for_fit(const torch::Tensor& state);
  // tanh(mu(s)): the deterministic action.
  torch::Tensor mean_action(const torch::Tensor& state);
  // The mean head and its tanh as one autograd node: dense_chain(mean_chain(), {state}) equals
  // mean_action().
  DenseChain mean_chain() const;
  // A reparameterised sample (gradients flow to the parameters) and its log-probability; the noise comes
  // from `generator` (LibTorch's default generator if none).
  PolicySample rsample(const torch::Tensor& state, c10::optional<at::Generator> generator = c10::nullopt);
  // A sample without gradients.
  PolicySample sample(const torch::Tensor& state);
  // log pi(action | state) for given actions in (-1, 1) (clamped to +-(1 - 1e-6) before atanh), [B, 1].
  torch::Tensor log_prob(const torch::Tensor& state, const torch::Tensor& action);

  // Log-density of u under N(mean, exp(log_std)^2) plus the tanh correction for a = tanh(u); [B, 1].
  static torch::Tensor squashed_log_prob(const torch::Tensor& u, const torch::Tensor& action,
                                         const torch::Tensor& mean, const torch::Tensor& log_std);

  // The state as the heads see it: (state relative to its references - offset) / scale with the options'
  // normalisation, else `state` itself. Differentiable.
  torch::Tensor normalize(const torch::Tensor& state) const;
  bool normalizes_inputs() const { return !options_.input_scale.empty(); }
  // The normalisation as tensors with `options` (a batched pass converts them once per planning call, not
  // per step). Precondition: normalizes_inputs().
  InputNormalisation input_normalisation(const torch::TensorOptions& options) const;

  const GaussianPolicyOptions& options() const { return options_; }
  torch::nn::ModuleList mean_layers{nullptr}, log_std_layers{nullptr};

 private:
  GaussianPolicyOptions options_;
  InputNormaliser normaliser_;
};
TORCH_MODULE(GaussianPolicy);

}  // namespace hlt
