// Training methods and the controllers they act with, each found by name. The baselines are
// parameterisations of the hybrid controllers (NN-MPPI: the stochastic planner with a noise sampler;
// model-based deterministic: the deterministic planner with no policy), not copies.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "hlt/control/controller.h"
#include "hlt/control/rollout_model.h"
#include "hlt/nn/dynamics_model.h"
#include "hlt/nn/gaussian_policy.h"
#include "hlt/nn/reward_model.h"
#include "hlt/nn/twin_q_network.h"
#include "hlt/util/config.h"

namespace hlt {

// One learner a method trains: which, on what data, and how often.
struct LearnerUse {
  std::string learner;      // a name in agents/learner_list.inc
  std::string data;         // kReplayData or kDemonstrationData
  std::string updates_key;  // config key: updates per agent step (online loop) or per iteration (imitation)
};

// The data sources a learner can sample from. The replay buffer D holds everything the agent did (and, in
// imitation, the demonstrations too); the demonstration buffer D_exp holds the expert's transitions alone.
inline constexpr const char* kReplayData = "replay";
inline constexpr const char* kDemonstrationData = "demonstrations";

// The outer loops: Alg. 1 and 2's (act, store, update at every agent step) and Alg. 3's (per iteration: one
// demonstration, the updates, one test episode).
inline constexpr const char* kOnlineLoop = "online";
inline constexpr const char* kImitationLoop = "imitation";

struct MethodSpec {
  std::string name;
  std::string loop;        // kOnlineLoop or kImitationLoop
  std::string controller;  // acts during training (the imitation loop's test episodes) and in evaluation
  std::string planner_controller;  // the model-based planner alone, for the component evaluation ("" if none)
  std::vector<LearnerUse> learners;  // in the order they are built, updated and logged
  std::string description;
};

// Throws hlt::Error listing the known methods.
const MethodSpec& find_method(const std::string& name);
std::vector<std::string> method_names();

// The learned components a controller may use; holders may be empty when a method does not learn them.
struct LearnedModels {
  GaussianPolicy policy{nullptr};
  DynamicsModel dynamics{nullptr};
  // With model.ensemble N > 1, the ensemble's other N - 1 dynamics models (`dynamics` is its first).
  std::vector<DynamicsModel> ensemble;
  RewardModel reward{nullptr};
  TwinQNetwork critics{nullptr};  // SAC's critics (not their target): the planner's terminal value
  // If set, the stochastic planners (hybrid-stochastic, NN-MPPI) roll out on this instead of the learned
  // dynamics and reward models (the tools' SimulatorRolloutModel: the planner with a perfect model).
  std::shared_ptr<RolloutModel> plan_on;
};

// The dynamics networks by checkpoint key: `first` as "dynamics", then each of `others` (an ensemble's
// other members) as "dynamics_member<i>", i = 1, 2, ...; none if `first` is empty.
std::vector<std::pair<std::string, DynamicsModel>> named_dynamics(const DynamicsModel& first,
                                                                  const std::vector<DynamicsModel>& others);

// Builds the controller registered as `name` from the config's planner settings. `evaluation` switches off
// training-time exploration (policy sampling, deterministic exploration noise).
std::unique_ptr<Controller> make_controller(const std::string& name, const LearnedModels& models,
                                            const Config& config, bool evaluation);
std::vector<std::string> controller_names();

}  // namespace hlt
