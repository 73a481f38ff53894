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

}  // namespace hlt
