// Training methods and the controllers they act with, each found by name. The baselines are
// parameterisations of the hybrid controllers (NN-MPPI: the stochastic planner with a noise sampler;
// model-based deterministic: the deterministic planner with no policy), not copies.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "hlt/control/controller.h"
#include "hlt/nn/dynamics_model.h"
#include "hlt/nn/gaussian_policy.h"
#include "hlt/nn/reward_model.h"
#include "hlt/util/config.h"

namespace hlt {

struct MethodSpec {
  std::string name;
  std::string controller;          // acts during training and in the method's own evaluation
  std::string planner_controller;  // the model-based planner alone, for the component evaluation ("" if none)
  bool trains_policy = false;      // SAC updates
  bool trains_models = false;      // dynamics + reward updates
  std::string description;
};

// Throws hlt::Error listing the known methods.
const MethodSpec& find_method(const std::string& name);
std::vector<std::string> method_names();

// The learned components a controller may use; holders may be empty when a method does not learn them.
struct LearnedModels {
  GaussianPolicy policy{nullptr};
  DynamicsModel dynamics{nullptr};
  RewardModel reward{nullptr};
};

// Builds the controller registered as `name` from the config's planner settings. `evaluation` switches off
// training-time exploration (policy sampling, deterministic exploration noise).
std::unique_ptr<Controller> make_controller(const std::string& name, const LearnedModels& models,
                                            const Config& config, bool evaluation);
std::vector<std::string> controller_names();

}  // namespace hlt
