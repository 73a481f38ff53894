#include "hlt/nn/activation.h"

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

}  // namespace

void activate_out(at::Tensor& out, const at::Tensor& x, Activation a) {
  if (a == Activation::kSin) {
    if (vector_kernels_apply(x)) {
      out.resize_(x.sizes());
      vector_sin(x.data_ptr<float>(), out.data_ptr<float>(), x.numel());
    } else {
      at::sin_out(out, x);
    }
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
  if (a == Activation::kSin) {
    cosine_out(scratch, x);
    grad.mul_(scratch);
  } else {
    relu_gradient_of(y, grad);
  }
}

}  // namespace hlt
