// hlt::Controller: what turns an observed state into an action in [-1, 1]^m. The hybrid controllers, their
// model-based baselines and the plain policy all implement it.
//
// The base class owns the numerical safety net: if a controller's action is not finite (a NaN weight or
// model output), the step falls back to the policy's mean action (or zero when there is no policy), the
// event is counted, and the environment never sees the non-finite value.
#pragma once

#include <cstdint>
#include <limits>
#include <string>

#include <ATen/core/Tensor.h>

#include "hlt/nn/gaussian_policy.h"

namespace hlt {

struct ControllerDiagnostics {
  // Mode insertion gradient of the last step (deterministic hybrid controllers); NaN when not defined.
  double mode_insertion_gradient = std::numeric_limits<double>::quiet_NaN();
  // Stochastic planners, step 0 of the last call: the effective number of samples 1 / sum_k w_k^2 (1: the
  // weights sit on one sample, K: uniform) and the weight on samples with a saturated action (|v| > 0.99 in
  // some dimension). NaN when not defined.
  double weight_ess = std::numeric_limits<double>::quiet_NaN();
  double saturated_weight = std::numeric_limits<double>::quiet_NaN();
  bool fell_back = false;  // the last step used the fallback action
  int64_t fallbacks = 0;   // fallback steps since construction
};

class Controller {
 public:
  // `fallback_policy` may be empty (nullptr holder): then the fallback is the zero action.
  explicit Controller(GaussianPolicy fallback_policy) : fallback_policy_(std::move(fallback_policy)) {}
  virtual ~Controller() = default;

  virtual std::string name() const = 0;
  // Called at the start of every episode (clears warm starts).
  virtual void reset() {}
  // How many agent steps the learning run has taken (environment interactions), for controllers whose
  // exploration decays with experience (the deterministic hybrid's 0.999^t); others ignore it.
  virtual void set_interactions(int64_t /*t*/) {}
  // The action for state [n] (any float dtype; computed in the models' dtype), returned as [m] in [-1, 1].
  at::Tensor act(const at::Tensor& state);
  const ControllerDiagnostics& diagnostics() const { return diagnostics_; }

 protected:
  virtual at::Tensor compute_action(const at::Tensor& state) = 0;
  ControllerDiagnostics diagnostics_;

 private:
  GaussianPolicy fallback_policy_;
};

}  // namespace hlt
