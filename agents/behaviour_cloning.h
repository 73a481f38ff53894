// hlt::BehaviourCloning: trains the Gaussian policy on demonstrations by maximum likelihood, minimising
// -E[log pi(a_expert | s)] with Adam (paper appendix: lr 0.01). The policy is shared with the controllers
// that act with it, as SAC's is.
//
// An expert's action at the bound of the action range was clipped there: the expert asked for at least
// that much. With `censor_saturated` such a component is a censored observation and contributes
// log P(tanh(u) >= kCensorLevel) = log Phi((mu - atanh(kCensorLevel)) / sigma) (mirrored at -1), not the
// density at atanh(1 - 1e-6) = 7.25, a target far outside the others that the policy's mean and
// standard deviation are otherwise bent to reach (the Ant expert's actions are 38 % at the bound).
#pragma once

#include <memory>
#include <vector>

#include <ATen/core/Tensor.h>

#include "agents/learner.h"
#include "hlt/nn/flat_adam.h"
#include "hlt/nn/gaussian_policy.h"

namespace hlt {

struct BehaviourCloningOptions {
  double lr = 0.01;
  bool censor_saturated = true;
  // L2 penalty 0.5 * weight_decay * |W|^2 on the policy's weight matrices (not its biases).
  double weight_decay = 0.0;
  // Each batch's states are perturbed by Gaussian noise of input_noise times the batch's standard deviation
  // of that component before the loss (0: none): the policy is asked for the expert's action near, not
  // only at, the demonstrated states.
  double input_noise = 0.0;
};

// An action component with |a| >= kSaturatedAt is at the bound; as a censored observation it says
// |tanh(u)| >= kCensorLevel.
inline constexpr double kSaturatedAt = 1.0 - 1e-6;
inline constexpr double kCensorLevel = 0.999;

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
  BehaviourCloningOptions options_;
  std::unique_ptr<FlatAdam> optimizer_;
  std::vector<at::Tensor> decayed_;  // the weight matrices, views into the optimizer's buffer
};

}  // namespace hlt
