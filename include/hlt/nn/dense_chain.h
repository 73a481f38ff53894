// hlt::dense_chain: a network of dense layers evaluated as a single LibTorch autograd node.
//
// y = squash(W_L act(... act(W_1 [x_1, ..., x_k] + b_1) ...) + b_L) (+ x_1 with a residual), where squash
// is tanh or the identity. Through a module's own forward the same network records one autograd node per
// op (cat, linear, activation, add), and at the deterministic planner's sizes the engine's per-node cost,
// not the matrix products, is most of a Jacobian pass (docs/BENCHMARKS.md). As one node, with its
// vector-Jacobian product written out layer by layer, the pass keeps autograd's interface
// (torch::autograd::grad with any seeds) at a fraction of the cost. Inside the node the products call the
// process's BLAS gemm directly (the one ATen's products use) and the elementwise work runs over raw
// buffers. Gradients reach the inputs and the weights, each computed only if the engine asks for it; the
// values equal the module's forward to float rounding (tests/core/dense_chain_test.cpp checks both passes
// against autograd through the modules and against finite differences).
#pragma once

#include <vector>

#include <ATen/core/Tensor.h>
#include <torch/nn/modules/linear.h>

#include "hlt/nn/activation.h"

namespace hlt {

// The layers (held, not copied) and what sits between and after them.
struct DenseChain {
  std::vector<torch::nn::Linear> layers;
  Activation hidden = Activation::kRelu;  // after every layer but the last
  bool tanh_output = false;
  // Adds the first input to the output (the dynamics model's s' = s + ...); its width must be the output's.
  bool residual = false;
};

// The chain on `inputs` [B, in_i], concatenated along columns (their widths must add up to the first layer's
// input). Differentiable with respect to the inputs and every layer's weight and bias.
at::Tensor dense_chain(const DenseChain& chain, at::TensorList inputs);

}  // namespace hlt
