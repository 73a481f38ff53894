#include "hlt/nn/activation.h"

#include <ATen/ATen.h>

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

void activate_out(at::Tensor& out, const at::Tensor& x, Activation a) {
  if (a == Activation::kSin)
    at::sin_out(out, x);
  else
    at::clamp_min_out(out, x, 0);  // relu
}

void activation_backward_(at::Tensor& grad, const at::Tensor& x, const at::Tensor& y, Activation a,
                          at::Tensor& scratch) {
  if (a == Activation::kSin) {
    at::cos_out(scratch, x);
    grad.mul_(scratch);
  } else {
    // ReLU's derivative is 1 where its output is positive (autograd's threshold_backward).
    at::threshold_backward_out(grad, grad, y, 0.0);
  }
}

}  // namespace hlt
