// hlt::PolicyController: acts with the policy alone, sampling (training, SAC's exploration) or with its
// mean action (evaluation).
#pragma once

#include "hlt/control/controller.h"

namespace hlt {

class PolicyController : public Controller {
 public:
  PolicyController(GaussianPolicy policy, bool deterministic);
  std::string name() const override { return deterministic_ ? "policy_mean" : "policy"; }
  void set_deterministic(bool d) { deterministic_ = d; }

 protected:
  at::Tensor compute_action(const at::Tensor& state) override;

 private:
  GaussianPolicy policy_;
  bool deterministic_;
};

}  // namespace hlt
