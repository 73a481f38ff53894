// hlt::InputNormaliser: a fixed affine map in front of a network's state input, x = (M s - offset) / scale,
// where M subtracts from component i the component it is read relative to (its reference), so that a block's
// position is seen relative to the gripper's, say, at the millimetres that decide a grasp. A fixed part of
// the network's function, like its activation: the policy and the learned models apply it in every way
// they are evaluated (module forward, hand-written passes, autograd chains, the planners' batched passes).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <torch/nn/modules/linear.h>
#include <torch/types.h>

namespace hlt {

// The normalisation as tensors: x = (s map_t - offset) * inv_scale, with map_t ([n, n]) undefined when no
// component has a reference.
struct InputNormalisation {
  torch::Tensor offset, inv_scale, map_t;
};

class InputNormaliser {
 public:
  // None: apply() is the identity.
  InputNormaliser() = default;
  // Offsets and scales for all `dim` components (both empty: none), scales finite and > 0; references
  // (empty: none; needs the normalisation) -1 or another component, read from the raw state. Errors name
  // `owner`.
  InputNormaliser(int64_t dim, const std::vector<double>& offset, const std::vector<double>& scale,
                  const std::vector<int64_t>& reference, const std::string& owner);

  bool enabled() const { return offset_.defined(); }
  // The tensors with `options` (a batched pass converts them once per planning call, not per step).
  // Precondition: enabled().
  InputNormalisation tensors(const torch::TensorOptions& options) const;
  // x for states [B, dim] (rows contiguous or not); `state` itself when not enabled. Differentiable.
  torch::Tensor apply(const torch::Tensor& state) const;
  // Normalises the first dim columns of x [B, >= dim] in place (the hand-written passes' input buffers).
  void apply_in_place(const torch::Tensor& x) const;
  // A new layer equal to `first` (which reads [s, ...], s in its first dim input columns) on the raw state:
  // W_s ((M s - c) / d) + b = ((W_s / d) M) s + (b - W_s (c / d)), the other columns as they are. A copy (no
  // gradient reaches `first` through it), made without drawing from the default generator. Precondition:
  // enabled().
  torch::nn::Linear fold_into(const torch::nn::Linear& first) const;
  // Whether both apply the same map (both none, or equal offsets, scales and references).
  bool same_as(const InputNormaliser& other) const;

 private:
  int64_t dim_ = 0;
  torch::Tensor offset_, inv_scale_, map_t_;  // float64; undefined without normalisation (map_t_: references)
};

}  // namespace hlt
