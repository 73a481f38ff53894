// Dense-layer passes written with ATen's out= kernels into caller-owned buffers, for the learners whose
// gradients are written by hand (the model learner, SAC): without autograd's graph a layer's forward is one
// product and its backward two or three, and nothing is allocated once the buffers have their sizes.
//
// Weights use torch::nn::Linear's layout, [out, in]; biases are [out]. Every output tensor is resized by
// the kernel on first use, so an empty at::Tensor is a valid buffer.
#pragma once

#include <initializer_list>
#include <vector>

#include <ATen/core/Tensor.h>
#include <torch/nn/modules/container/modulelist.h>
#include <torch/nn/modules/linear.h>

#include "hlt/nn/activation.h"

namespace hlt {

// out = x W^T + b, [B, out].
void dense_forward(at::Tensor& out, const at::Tensor& x, const at::Tensor& weight, const at::Tensor& bias);

// From the gradient of the layer's output `grad_out` [B, out]: grad_weight = grad_out^T x and
// grad_bias = sum over the batch of grad_out, both written (not accumulated) into the given tensors, and
// grad_x = grad_out W [B, in] when it is not null.
void dense_backward(const at::Tensor& grad_out, const at::Tensor& x, const at::Tensor& weight,
                    at::Tensor& grad_weight, at::Tensor& grad_bias, at::Tensor* grad_x);

// An empty tensor to pass as the out= buffer of the functions above (ATen's out= ops need a defined
// tensor; they resize it on first use).
at::Tensor empty_buffer();
// Replaces every buffer whose dtype is not `like`'s by an empty one of that dtype (a network moved to
// float64 for a test needs float64 buffers).
void match_buffers(std::initializer_list<at::Tensor*> buffers, const at::Tensor& like);

// `buffer` with the given sizes (resized in place if it has others).
at::Tensor& sized(at::Tensor& buffer, at::IntArrayRef sizes);

// A parameter's .grad(), created as zeros if it has none yet (FlatAdam binds every parameter's gradient to
// its flat buffer; a network used without an optimizer, as in tests, gets its own).
at::Tensor& gradient_of(at::Tensor& parameter);

// A stack of torch::nn::Linear layers with one hidden activation (none after the last layer), run forward
// with its activations kept so that a hand-written backward pass can follow. It holds the layers, not
// copies: the gradients it writes are the layers' own .grad() tensors.
class DenseStack {
 public:
  DenseStack() = default;
  DenseStack(const torch::nn::ModuleList& layers, Activation hidden);

  // The stack's output for x [B, in], [B, out]; valid until the next forward.
  const at::Tensor& forward(const at::Tensor& x);
  // From d loss / d output of the last forward: writes (not accumulates) every layer's weight and bias
  // gradients. `grad_out` is used as scratch.
  void backward(at::Tensor& grad_out);

 private:
  std::vector<torch::nn::Linear> layers_;
  Activation hidden_ = Activation::kRelu;
  at::Tensor input_;
  std::vector<at::Tensor> pre_, post_, grad_;  // per hidden layer: before and after the activation
  at::Tensor output_ = empty_buffer(), scratch_ = empty_buffer();
};

}  // namespace hlt
