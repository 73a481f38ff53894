// The hidden-layer non-linearities the paper uses: sin for the swing-up tasks' dynamics and policy means,
// ReLU for locomotion.
#pragma once

#include <cstdint>
#include <string>

#include <ATen/core/Tensor.h>

namespace hlt {

enum class Activation { kSin, kRelu };

// "sin" or "relu"; anything else throws hlt::Error naming the allowed values.
Activation parse_activation(const std::string& name);
std::string activation_name(Activation a);
at::Tensor activate(const at::Tensor& x, Activation a);
// out = activate(x), into a caller-owned buffer (float sin through hlt's vector kernels: within 3.5 ulp).
void activate_out(at::Tensor& out, const at::Tensor& x, Activation a);
// out = cos(x), into a caller-owned buffer (float through hlt's vector kernels; not at::cos_out, which
// argument-dependent lookup would make ambiguous).
void cosine_out(at::Tensor& out, const at::Tensor& x);
// grad = 0 where ReLU's output y is not positive (its backward pass), in place.
void relu_gradient_of(const at::Tensor& y, at::Tensor& grad);
// grad *= d activate(x) / dx in place, given the forward's input x and output y; `scratch` is a buffer
// for sin's cos(x).
void activation_backward_(at::Tensor& grad, const at::Tensor& x, const at::Tensor& y, Activation a,
                          at::Tensor& scratch);

// The same over n contiguous values, without dispatched ops; the tensor forms above use them for contiguous
// float tensors. y = activate(x) (float sin through hlt's vector kernels, double through std::sin; ReLU keeps
// NaN and -0 as at::relu does). grad *= d activate(x) / dx given y = activate(x) (ReLU: 0 where y is not
// positive, as relu_gradient_of); `scratch` holds n values, for sin's cos(x).
void activate_values(const float* x, float* y, int64_t n, Activation a);
void activate_values(const double* x, double* y, int64_t n, Activation a);
void activation_gradient(float* grad, const float* x, const float* y, float* scratch, int64_t n,
                         Activation a);
void activation_gradient(double* grad, const double* x, const double* y, double* scratch, int64_t n,
                         Activation a);

}  // namespace hlt
