// Loading a trained policy from an hlt_train checkpoint as a PolicySource for tools (hlt_rollout). The
// checkpoint carries the policy's architecture, so no config is needed; the source acts with the policy's
// mean action. The learned dynamics and reward models load too, rebuilt from the run's config that the
// checkpoint holds, for tools that compare their predictions with the environment.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "envs/rollout.h"
#include "hlt/control/controller.h"
#include "hlt/control/rollout_model.h"
#include "hlt/nn/dynamics_model.h"
#include "hlt/nn/gaussian_policy.h"
#include "hlt/nn/reward_model.h"

namespace hlt {

struct SavedPolicy {
  std::unique_ptr<PolicySource> source;
  std::string env;                // the environment it was trained on
  std::string method;             // the method that trained it
  int frame_skip = 1;             // the frame skip it was trained with
  GaussianPolicyOptions options;  // the policy as rebuilt, its input normalisation included
};

// Throws hlt::Error if the file is not an hlt checkpoint or holds no policy (e.g. a baseline without one).
SavedPolicy load_saved_policy(const std::string& checkpoint_path);

struct SavedModels {
  DynamicsModel dynamics{nullptr};
  RewardModel reward{nullptr};
  std::string env;     // the environment they were trained on
  std::string method;  // the method that trained them
  int frame_skip = 1;  // the frame skip of their run: they predict one such step
};

// The checkpoint's dynamics and reward models (in evaluation mode), built as its run's config says (model.*,
// with the environment's declared observation ranges where model.normalize_inputs asks for them). Throws
// hlt::Error if the checkpoint holds no models (e.g. SAC or behaviour cloning).
SavedModels load_saved_models(const std::string& checkpoint_path);

struct SavedController {
  std::unique_ptr<Controller> controller;
  std::string env;
  std::string method;
  int frame_skip = 1;
};

// The controller registered as `controller` (agents/controller_list.inc, e.g. "stochastic_hybrid"), built
// for evaluation as the checkpoint's run builds it: its config's planner settings and its trained networks
// (the run's learners are rebuilt from its method and config, then loaded). With `plan_on` the stochastic
// planners roll out on it instead of the learned models. A run's checkpoint.pt gives the planner exactly as
// it trained; its final.pt holds the networks alone, without the dynamics model's domain
// (planner.clamp_to_data then clamps nothing) and SAC's critics (a planner.terminal_value then fails). Throws
// hlt::Error if the checkpoint lacks a network the controller needs.
// `overrides` (key=value, as hlt_train takes them) change the run's config before the controller is built,
// e.g. planner.lambda=0.1 (a setting that changes a network's shape is refused by the load).
SavedController load_saved_controller(const std::string& checkpoint_path, const std::string& controller,
                                      std::shared_ptr<RolloutModel> plan_on = nullptr,
                                      const std::vector<std::string>& overrides = {});

}  // namespace hlt
