// hlt::TwinQNetwork: SAC's two soft Q-functions Q_i(s, a) = MLP_i([s, a]) (ReLU hidden layers, 2 x 256 by
// default) evaluated as one batched network: layer l of both critics is one [2, in, out] weight, so a
// forward pass is one batched product per layer instead of two products and twice the ops.
#pragma once

#include <cstdint>
#include <vector>

#include <torch/nn/module.h>

#include <torch/nn/pimpl.h>
#include "hlt/nn/dense_layers.h"

namespace hlt {

struct TwinQNetworkOptions {
  int64_t state_dim = 0;
  int64_t action_dim = 0;
  std::vector<int64_t> hidden = {256, 256};
};

class TwinQNetworkImpl : public torch::nn::Module {
 public:
  // Each critic is initialised as torch::nn::Linear layers would be (critic 0's layers, then critic 1's).
  explicit TwinQNetworkImpl(const TwinQNetworkOptions& options);
  // Both critics' Q-values, [2, B, 1] (critic i at index i).
  torch::Tensor forward(const torch::Tensor& state, const torch::Tensor& action);
  // min_i Q_i(s, a), [B, 1]: the clipped double-Q estimate.
  torch::Tensor min_q(const torch::Tensor& state, const torch::Tensor& action);

  // The hand-written passes SAC's update uses instead of autograd. forward_keep is forward with every
  // layer's activations kept (valid until the next forward_keep); the two backward passes start from
  // d loss / d Q [2, B, 1] of that forward.
  const torch::Tensor& forward_keep(const torch::Tensor& state, const torch::Tensor& action);
  // Writes (not accumulates) every weight's and bias's gradient.
  void backward_parameters(const torch::Tensor& grad_q);
  // d loss / d action [B, m], summed over both critics; the parameters' gradients are left alone.
  torch::Tensor backward_action(const torch::Tensor& grad_q);

  const TwinQNetworkOptions& options() const { return options_; }

  std::vector<torch::Tensor> weights;  // layer l: [2, in_l, out_l]
  std::vector<torch::Tensor> biases;   // layer l: [2, 1, out_l]

 private:
  TwinQNetworkOptions options_;
  // forward_keep's activations: the input [B, n + m] and each layer's output (after its ReLU).
  torch::Tensor input_ = empty_buffer();
  std::vector<torch::Tensor> outputs_, grads_;
};
TORCH_MODULE(TwinQNetwork);

}  // namespace hlt
