#include "agents/behaviour_cloning.h"

#include <torch/torch.h>

#include "hlt/core/checkpoint.h"
#include "hlt/util/error.h"

namespace hlt {

BehaviourCloning::BehaviourCloning(GaussianPolicy policy, const BehaviourCloningOptions& options)
    : policy_(std::move(policy)) {
  optimizer_ = std::make_unique<FlatAdam>(policy_->parameters(), FlatAdamOptions{options.lr});
}

at::Tensor BehaviourCloning::nll(const at::Tensor& states, const at::Tensor& actions) {
  check(states.dim() == 2 && actions.dim() == 2 && states.size(0) == actions.size(0) && states.size(0) > 0,
        "behaviour cloning needs [B, n] states and [B, m] actions");
  return -policy_->log_prob(states, actions).mean();
}

double BehaviourCloning::loss(const at::Tensor& states, const at::Tensor& actions) {
  torch::NoGradGuard no_grad;
  return nll(states, actions).item<double>();
}

double BehaviourCloning::update(const at::Tensor& states, const at::Tensor& actions) {
  const at::Tensor l = nll(states, actions);
  optimizer_->zero_grad();
  l.backward();
  optimizer_->step();
  return l.item<double>();
}

void BehaviourCloning::save_training_state(CheckpointWriter& w) const {
  optimizer_->save(w, "bc");
}

void BehaviourCloning::load_training_state(CheckpointReader& r) {
  optimizer_->load(r, "bc");
}

}  // namespace hlt
