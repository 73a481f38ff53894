// hlt::ModelCheck: how well a learned dynamics model predicts transitions it was not trained on (an
// evaluation's, a rollout's), per observation component, against the error of predicting that nothing
// changes. A model worse than that constant is no help to a planner, however low its training loss; the
// trainer logs the ratio at every evaluation (eval/model_error_ratio) so that this shows in every run.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "envs/env.h"
#include "hlt/nn/dynamics_model.h"

namespace hlt {

struct ModelScore {
  Eigen::VectorXd error_rms;   // per component: rms of (predicted - actual next observation)
  Eigen::VectorXd change_rms;  // per component: rms of (actual next - current observation), the error of
                               // predicting "no change"
  Eigen::VectorXd spread;      // per component: standard deviation of the observations themselves
  Eigen::VectorXd unit;        // per component: what its errors are measured in (see score())
  // The errors against the changes, each component measured in its unit (so that units do not matter) and
  // pooled: sqrt(sum_i (error_rms_i / unit_i)^2 / sum_i (change_rms_i / unit_i)^2) over the components with
  // a unit. 1 for a model that predicts "no change", 0 for an exact one, above 1 for one that is worse
  // than the constant (e.g. one that moves what stood still). NaN if nothing changed or the model
  // predicted NaN.
  double error_ratio = std::numeric_limits<double>::quiet_NaN();
  int better = 0;  // components with error_rms < change_rms
  int64_t transitions = 0;
};

class ModelCheck {
 public:
  // One transition (o, a, o'). Every transition must have the sizes of the first.
  void add(const Eigen::VectorXd& observation, const Eigen::VectorXd& action, const Eigen::VectorXd& next);
  int64_t size() const { return size_; }
  void clear();
  // The model's one-step predictions of every added o' from (o, a), in inference mode. `units` are the
  // components' typical ranges where the environment declares them (Env::observation_scale()'s scale);
  // without, each component's spread over the added observations is its unit, and a component whose
  // spread is below 1e-6 of the largest one counts as constant and is left out (a block that never moves
  // would otherwise turn a micrometre of predicted motion into an arbitrarily large ratio). Preconditions:
  // size() > 0, the model's state and action sizes are the transitions', units (if given) has one positive
  // entry per component.
  ModelScore score(DynamicsModelImpl& model,
                   const std::optional<Eigen::VectorXd>& units = std::nullopt) const;
  // The same, in the units `env` declares (its observation_scale()'s scale), if it declares any.
  ModelScore score(DynamicsModelImpl& model, const Env& env) const;

 private:
  std::vector<double> observations_, actions_, next_;
  int64_t n_ = -1, m_ = -1, size_ = 0;
};

}  // namespace hlt
