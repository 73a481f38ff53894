// hlt::DynamicsModel: the learned one-step model s' = s + W2 act(W1 [x(s), a] + b1) + b2 (paper appendix,
// "Models"; x(s) = s unless the options ask for input normalisation), with a learned state-independent
// log-std used only by its Gaussian negative log-likelihood.
#pragma once

#include <cstdint>
#include <vector>

#include <torch/nn/module.h>

#include <torch/nn/modules/linear.h>
#include "hlt/nn/dense_layers.h"

#include "hlt/nn/activation.h"
#include "hlt/nn/dense_chain.h"
#include "hlt/nn/input_normalisation.h"

namespace hlt {

struct DynamicsModelOptions {
  int64_t state_dim = 0;
  int64_t action_dim = 0;
  int64_t hidden = 200;
  Activation activation = Activation::kSin;
  double log_std_min = -10.0;
  double log_std_max = 2.0;
  // Input normalisation of the state (as GaussianPolicyOptions'; all empty: none). The residual adds the raw
  // state: only what the network reads is normalised.
  std::vector<double> input_offset, input_scale;
  std::vector<int64_t> input_reference;
};

class DynamicsModelImpl : public torch::nn::Module {
 public:
  explicit DynamicsModelImpl(const DynamicsModelOptions& options);

  // Predicted next state, [B, n], from states [B, n] and actions [B, m].
  torch::Tensor forward(const torch::Tensor& state, const torch::Tensor& action);
  // The mean network as one autograd node: dense_chain(chain(), {state, action}) equals forward().
  DenseChain chain() const;
  // The clamped log-std, [1, n].
  torch::Tensor log_std() const;
  // -mean over batch and state dimensions of log N(next_state; forward(state, action), exp(log_std)^2).
  torch::Tensor loss(const torch::Tensor& state, const torch::Tensor& action,
                     const torch::Tensor& next_state);
  // The same loss's value, with `scale` times its gradient written (not accumulated) into the parameters'
  // .grad() tensors by a hand-written backward pass (tested against autograd) instead of a graph.
  double loss_with_gradient(const torch::Tensor& state, const torch::Tensor& action,
                            const torch::Tensor& next_state, double scale = 1.0);
  // The open-loop (multi-step) loss: from `state` [B, n] the model predicts K = actions.size(0) / B steps
  // ahead on its own predictions, s^_{k+1} = forward(s^_k, a_k), and the loss is the mean over k of the
  // Gaussian NLL of the reached state next_states_k under s^_{k+1}. `actions` [K B, m] and `next_states`
  // [K B, n] are time-major (Batch's layout with steps K). With K = 1 it equals loss().
  torch::Tensor rollout_loss(const torch::Tensor& state, const torch::Tensor& actions,
                             const torch::Tensor& next_states);
  // rollout_loss's value with `scale` times its gradient written (not accumulated) into the parameters'
  // .grad() tensors (by autograd through the K steps; call outside inference mode).
  double rollout_loss_with_gradient(const torch::Tensor& state, const torch::Tensor& actions,
                                    const torch::Tensor& next_states, double scale = 1.0);

  const DynamicsModelOptions& options() const { return options_; }
  const InputNormaliser& normaliser() const { return normaliser_; }
  torch::nn::Linear fc1{nullptr}, fc2{nullptr};
  torch::Tensor log_std_param;

  // The model's domain: per state dimension, the least and greatest value of the states it was trained on
  // (its learner extends it with every batch's states and next states). A planner can keep its predicted
  // states inside it, where the model has data, instead of letting it extrapolate (planner.clamp_to_data).
  // Undefined tensors until the first extend_domain().
  void extend_domain(const torch::Tensor& states);
  void set_domain(const torch::Tensor& low, const torch::Tensor& high);
  bool has_domain() const { return domain_low_.defined(); }
  // [n] each, the model's dtype.
  const torch::Tensor& domain_low() const { return domain_low_; }
  const torch::Tensor& domain_high() const { return domain_high_; }

 private:
  DynamicsModelOptions options_;
  InputNormaliser normaliser_;
  torch::Tensor domain_low_, domain_high_;
  // loss_with_gradient's buffers, kept between calls.
  torch::Tensor x_ = empty_buffer(), h_ = empty_buffer(), act_ = empty_buffer(), mean_ = empty_buffer(),
                z_ = empty_buffer(), g_mean_ = empty_buffer(), g_act_ = empty_buffer(), cos_ = empty_buffer();
};
TORCH_MODULE(DynamicsModel);

}  // namespace hlt
