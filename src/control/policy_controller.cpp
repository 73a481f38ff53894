#include "hlt/control/policy_controller.h"

#include <torch/torch.h>

#include "hlt/util/error.h"

namespace hlt {

PolicyController::PolicyController(GaussianPolicy policy, bool deterministic)
    : Controller(policy), policy_(std::move(policy)), deterministic_(deterministic) {
  check(!policy_.is_empty(), "PolicyController needs a policy");
}

at::Tensor PolicyController::compute_action(const at::Tensor& state) {
  torch::InferenceMode guard;
  const auto dtype = policy_->parameters().front().scalar_type();
  const at::Tensor s = state.to(dtype).unsqueeze(0);
  return (deterministic_ ? policy_->mean_action(s) : policy_->rsample(s).action).squeeze(0);
}

}  // namespace hlt
