// The hidden-layer non-linearities the paper uses: sin for the swing-up tasks' dynamics and policy means,
// ReLU for locomotion.
#pragma once

#include <string>

#include <ATen/core/Tensor.h>

namespace hlt {

enum class Activation { kSin, kRelu };

// "sin" or "relu"; anything else throws hlt::Error naming the allowed values.
Activation parse_activation(const std::string& name);
std::string activation_name(Activation a);
at::Tensor activate(const at::Tensor& x, Activation a);

}  // namespace hlt
