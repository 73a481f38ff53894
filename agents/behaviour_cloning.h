// hlt::BehaviourCloning: trains the Gaussian policy on demonstrations by maximum likelihood, minimising
// -E[log pi(a_expert | s)] with Adam (paper appendix: lr 0.01). The policy is shared with the controllers
// that act with it, as SAC's is.
#pragma once

#include <memory>

#include <ATen/core/Tensor.h>

#include "agents/learner.h"
#include "hlt/nn/flat_adam.h"
#include "hlt/nn/gaussian_policy.h"

namespace hlt {

struct BehaviourCloningOptions {
  double lr = 0.01;
};

class BehaviourCloning : public Learner {
 public:
  BehaviourCloning(GaussianPolicy policy, const BehaviourCloningOptions& options);

  // The negative log-likelihood of `actions` ([B, m], in [-1, 1]) at `states` ([B, n]), without a step.
  double loss(const at::Tensor& states, const at::Tensor& actions);
  // One Adam step on that loss; returns the loss before the step.
  double update(const at::Tensor& states, const at::Tensor& actions);
  // The Learner view of update on a batch's states and actions: loss/bc.
  const char* learner_name() const override { return "behaviour cloning"; }
  NamedLosses train(const Batch& batch) override;

  GaussianPolicy& policy() { return policy_; }
  // The optimizer's state (the policy is checkpointed with the other shared networks).
  void save_training_state(CheckpointWriter& writer) const override;
  void load_training_state(CheckpointReader& reader) override;

 private:
  at::Tensor nll(const at::Tensor& states, const at::Tensor& actions);
  GaussianPolicy policy_;
  std::unique_ptr<FlatAdam> optimizer_;
};

}  // namespace hlt
