// What the tests of a stochastic planner on a given RolloutModel (the simulator, a distorted simulator) start
// from: an untrained policy to sample from and the planner's settings.
#pragma once

#include <memory>
#include <string>

#include "agents/methods.h"
#include "agents/train_config.h"
#include "envs/env.h"
#include "hlt/control/rollout_model.h"

namespace hlt::testing {

// An untrained Gaussian policy for `env` (one hidden layer of 16) whose planners plan on `plan_on`.
inline LearnedModels untrained_policy_planning_on(const Env& env, std::shared_ptr<RolloutModel> plan_on) {
  LearnedModels models;
  GaussianPolicyOptions po;
  po.state_dim = env.observation_dim();
  po.action_dim = env.action_dim();
  po.hidden = {16};
  models.policy = GaussianPolicy(po);
  models.plan_on = std::move(plan_on);
  return models;
}

// The default config with the planner's horizon, samples and temperature set.
inline Config planner_config(int horizon, int samples, double lambda) {
  Config config = make_train_config();
  config.set("planner.horizon", std::to_string(horizon));
  config.set("planner.samples", std::to_string(samples));
  config.set("planner.lambda", std::to_string(lambda));
  return config;
}

}  // namespace hlt::testing
