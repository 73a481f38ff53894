#include "hlt/nn/activation.h"

#include <cmath>

#include <ATen/ATen.h>

#include "hlt/simd/vector_math.h"
#include "hlt/util/error.h"

namespace hlt {

Activation parse_activation(const std::string& name) {
  if (name == "sin") return Activation::kSin;
  if (name == "relu") return Activation::kRelu;
  throw Error(fmt::format("unknown activation '{}'; allowed: sin, relu", name));
}

std::string activation_name(Activation a) {
  return a == Activation::kSin ? "sin" : "relu";
}

at::Tensor activate(const at::Tensor& x, Activation a) {
  return a == Activation::kSin ? at::sin(x) : at::relu(x);
}

namespace {

// True where hlt's vector kernels apply: float, contiguous.
bool vector_kernels_apply(const at::Tensor& x) {
  return x.scalar_type() == at::kFloat && x.is_contiguous();
}

void sin_values(const float* x, float* y, int64_t n) {
  vector_sin(x, y, n);
}
void sin_values(const double* x, double* y, int64_t n) {
  for (int64_t i = 0; i < n; ++i)
    y[i] = std::sin(x[i]);
}
void cos_values(const float* x, float* y, int64_t n) {
  vector_cos(x, y, n);
}
void cos_values(const double* x, double* y, int64_t n) {
  for (int64_t i = 0; i < n; ++i)
    y[i] = std::cos(x[i]);
}
void relu_gradient_values(const float* y, float* grad, int64_t n) {
  relu_gradient(y, grad, n);
}
void relu_gradient_values(const double* y, double* grad, int64_t n) {
  for (int64_t i = 0; i < n; ++i)
    grad[i] = y[i] > 0 ? grad[i] : 0.0;
}

template <typename T>
void activate_values_impl(const T* x, T* y, int64_t n, Activation a) {
  if (a == Activation::kSin) {
    sin_values(x, y, n);
  } else {
    for (int64_t i = 0; i < n; ++i)
      y[i] = x[i] < 0 ? T(0) : x[i];
  }
}

template <typename T>
void activation_gradient_impl(T* grad, const T* x, const T* y, T* scratch, int64_t n, Activation a) {
  if (a == Activation::kSin) {
    cos_values(x, scratch, n);
    for (int64_t i = 0; i < n; ++i)
      grad[i] *= scratch[i];
  } else {
    relu_gradient_values(y, grad, n);
  }
}

}  // namespace

void activate_values(const float* x, float* y, int64_t n, Activation a) {
  activate_values_impl(x, y, n, a);
}
void activate_values(const double* x, double* y, int64_t n, Activation a) {
  activate_values_impl(x, y, n, a);
}
void activation_gradient(float* grad, const float* x, const float* y, float* scratch, int64_t n,
                         Activation a) {
  activation_gradient_impl(grad, x, y, scratch, n, a);
}
void activation_gradient(double* grad, const double* x, const double* y, double* scratch, int64_t n,
                         Activation a) {
  activation_gradient_impl(grad, x, y, scratch, n, a);
}

void activate_out(at::Tensor& out, const at::Tensor& x, Activation a) {
  if (vector_kernels_apply(x) && out.scalar_type() == at::kFloat) {
    out.resize_(x.sizes());
    activate_values(x.data_ptr<float>(), out.data_ptr<float>(), x.numel(), a);
  } else if (a == Activation::kSin) {
    at::sin_out(out, x);
  } else {
    at::clamp_min_out(out, x, 0);  // relu
  }
}

void cosine_out(at::Tensor& out, const at::Tensor& x) {
  if (vector_kernels_apply(x) && out.scalar_type() == at::kFloat) {
    out.resize_(x.sizes());
    vector_cos(x.data_ptr<float>(), out.data_ptr<float>(), x.numel());
  } else {
    at::cos_out(out, x);
  }
}

void relu_gradient_of(const at::Tensor& y, at::Tensor& grad) {
  if (vector_kernels_apply(y) && vector_kernels_apply(grad) && y.numel() == grad.numel()) {
    relu_gradient(y.data_ptr<float>(), grad.data_ptr<float>(), y.numel());
  } else {
    // ReLU's derivative is 1 where its output is positive (autograd's threshold_backward).
    at::threshold_backward_out(grad, grad, y, 0.0);
  }
}

void activation_backward_(at::Tensor& grad, const at::Tensor& x, const at::Tensor& y, Activation a,
                          at::Tensor& scratch) {
  if (vector_kernels_apply(grad) && vector_kernels_apply(x) && vector_kernels_apply(y) &&
      grad.numel() == x.numel() && y.numel() == x.numel() &&
      (a != Activation::kSin || (scratch.defined() && scratch.scalar_type() == at::kFloat))) {
    if (a == Activation::kSin) scratch.resize_(x.sizes());
    activation_gradient(grad.data_ptr<float>(), x.data_ptr<float>(), y.data_ptr<float>(),
                        a == Activation::kSin ? scratch.data_ptr<float>() : nullptr, x.numel(), a);
  } else if (a == Activation::kSin) {
    cosine_out(scratch, x);
    grad.mul_(scratch);
  } else {
    relu_gradient_of(y, grad);
  }
}

}  // namespace hlt
