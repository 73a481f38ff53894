#include "hlt/control/controller.h"

#include <torch/torch.h>

#include "hlt/nn/batched_forward.h"
#include "hlt/util/error.h"

namespace hlt {

at::Tensor Controller::act(const at::Tensor& state) {
  check(state.dim() == 1, "{}: state must be a vector, got {} dimensions", name(), state.dim());
  at::Tensor action = compute_action(state).contiguous();
  diagnostics_.fell_back = false;
  bool finite = true;
  dispatch_floating(action, [&](auto tag) {
    using T = decltype(tag);
    finite = Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, 1>>(action.data_ptr<T>(), action.numel())
                 .allFinite();
  });
  if (!finite) {
    // A NaN weight or model output must never reach the environment.
    diagnostics_.fell_back = true;
    ++diagnostics_.fallbacks;
    at::Tensor fallback;
    if (fallback_policy_) {
      torch::InferenceMode guard;
      const auto dtype = fallback_policy_->parameters().front().scalar_type();
      fallback = fallback_policy_->mean_action(state.to(dtype).unsqueeze(0)).squeeze(0);
    }
    if (!fallback.defined() || !torch::isfinite(fallback).all().item<bool>()) {
      fallback = torch::zeros_like(action);
    }
    action = fallback;
  }
  dispatch_floating(action, [&](auto tag) {
    using T = decltype(tag);
    auto a = Eigen::Map<Eigen::Matrix<T, Eigen::Dynamic, 1>>(action.data_ptr<T>(), action.numel()).array();
    a = a.max(T(-1)).min(T(1));
  });
  return action;
}

}  // namespace hlt
