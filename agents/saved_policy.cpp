#include "agents/saved_policy.h"

#include <torch/torch.h>

#include "agents/controller_policy.h"
#include "agents/learner.h"
#include "agents/methods.h"
#include "agents/train_config.h"
#include "envs/registry.h"
#include "hlt/core/checkpoint.h"
#include "hlt/nn/gaussian_policy.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

class CheckpointPolicy : public PolicySource {
 public:
  CheckpointPolicy(GaussianPolicy policy, std::string description)
      : policy_(std::move(policy)), description_(std::move(description)) {}
  std::string describe() const override { return description_; }
  Eigen::VectorXd act(const Eigen::VectorXd& observation) override {
    torch::InferenceMode guard;
    return action_vector(policy_->mean_action(observation_tensor(observation).unsqueeze(0)));
  }

 private:
  GaussianPolicy policy_;
  std::string description_;
};

// The run a checkpoint came from: its environment, method and frame skip.
template <typename Saved>
void read_run(CheckpointReader& r, Saved& out) {
  out.env = r.get_string("env");
  out.method = r.get_string("method");
  out.frame_skip = static_cast<int>(r.get_int("frame_skip"));
}

// The resolved config the checkpoint's run wrote, with `overrides` (key=value) applied.
Config stored_config(CheckpointReader& r, const std::vector<std::string>& overrides = {}) {
  Config config = make_train_config();
  config.merge_yaml(r.get_string("config"), r.path());
  for (const std::string& kv : overrides)
    config.apply_override(kv);
  return config;
}

// The learners `names` (in that order, as the run built them) create the run's networks in `models`, sized by
// its environment; their initial weights are for the caller to overwrite from the checkpoint. `config` must
// outlive the learners.
std::vector<std::unique_ptr<Learner>> build_learners(const Config& config, const std::string& env_name,
                                                     const std::vector<std::string>& names,
                                                     LearnedModels& models) {
  const std::unique_ptr<Env> env = make_env(env_name);
  LearnerContext context{config, env->observation_dim(),  env->action_dim(), 0,
                         models, env->observation_scale()};
  std::vector<std::unique_ptr<Learner>> learners;
  for (const std::string& name : names)
    learners.push_back(make_learner(name, context));
  return learners;
}

}  // namespace

SavedPolicy load_saved_policy(const std::string& path) {
  CheckpointReader r(path);
  SavedPolicy out;
  read_run(r, out);
  check(r.has("policy_hidden"), "checkpoint {} holds no policy (it was written by method '{}')", path,
        out.method);
  const at::Tensor hidden = r.tensor("policy_hidden");
  GaussianPolicyOptions o;
  o.hidden.assign(hidden.data_ptr<int64_t>(), hidden.data_ptr<int64_t>() + hidden.numel());
  o.mean_activation = parse_activation(r.get_string("policy_activation"));
  // The observation and action sizes are read off the stored first and last layers.
  torch::Tensor w_in, w_out;
  auto& archive = r.archive("module.policy");
  check(archive.try_read("mean.0.weight", w_in) &&
            archive.try_read(fmt::format("mean.{}.weight", o.hidden.size()), w_out),
        "checkpoint {}: the policy's layers are missing", path);
  o.state_dim = w_in.size(1);
  o.action_dim = w_out.size(0);
  if (r.has("policy_input_scale")) {
    const at::Tensor offset = r.tensor("policy_input_offset").to(torch::kFloat64).contiguous();
    const at::Tensor scale = r.tensor("policy_input_scale").to(torch::kFloat64).contiguous();
    o.input_offset.assign(offset.data_ptr<double>(), offset.data_ptr<double>() + offset.numel());
    o.input_scale.assign(scale.data_ptr<double>(), scale.data_ptr<double>() + scale.numel());
    if (r.has("policy_input_reference")) {
      const at::Tensor ref = r.tensor("policy_input_reference").to(torch::kInt64).contiguous();
      o.input_reference.assign(ref.data_ptr<int64_t>(), ref.data_ptr<int64_t>() + ref.numel());
    }
  }
  GaussianPolicy policy(o);
  r.load_module("policy", *policy);
  policy->eval();
  out.options = o;
  out.source = std::make_unique<CheckpointPolicy>(
      policy, fmt::format("policy mean from {} ({} on {})", path, out.method, out.env));
  return out;
}

SavedModels load_saved_models(const std::string& path) {
  CheckpointReader r(path);
  SavedModels out;
  read_run(r, out);
  check(r.has("dynamics") && r.has("reward"),
        "checkpoint {} holds no dynamics and reward models (it was written by method '{}')", path,
        out.method);
  const Config config = stored_config(r);
  LearnedModels models;
  // The model learner's factory builds both networks exactly as the run did.
  build_learners(config, out.env, {"models"}, models);
  r.load_module("dynamics", *models.dynamics);
  r.load_module("reward", *models.reward);
  models.dynamics->eval();
  models.reward->eval();
  out.dynamics = models.dynamics;
  out.reward = models.reward;
  return out;
}

SavedController load_saved_controller(const std::string& path, const std::string& controller,
                                      std::shared_ptr<RolloutModel> plan_on,
                                      const std::vector<std::string>& overrides) {
  CheckpointReader r(path);
  SavedController out;
  read_run(r, out);
  const Config config = stored_config(r, overrides);
  LearnedModels models;
  // The run's learners in its method's order build its networks.
  std::vector<std::string> names;
  for (const LearnerUse& use : find_method(out.method).learners)
    names.push_back(use.learner);
  const std::vector<std::unique_ptr<Learner>> learners = build_learners(config, out.env, names, models);
  // As the trainer resumes: the shared networks, then each learner's own state (SAC's critics, the
  // dynamics model's domain) where the file has it.
  auto load = [&](const std::string& name, auto& module) {
    if (module.is_empty()) return;
    check(r.has(name), "checkpoint {} holds no '{}' network", path, name);
    r.load_module(name, *module);
  };
  load("policy", models.policy);
  for (auto [key, m] : named_dynamics(models.dynamics, models.ensemble))
    load(key, m);
  load("reward", models.reward);
  // A run's checkpoint.pt (not its final.pt, which holds the networks alone) has them.
  if (r.has("torch_rng")) {
    for (auto& learner : learners)
      learner->load_training_state(r);
  } else {
    // The critics were built but not trained: leave them out, so that a controller that needs them (the
    // terminal value) says so instead of acting on freshly initialised ones.
    models.critics = nullptr;
  }
  auto evaluation_mode = [](auto& module) {
    if (!module.is_empty()) module->eval();
  };
  evaluation_mode(models.policy);
  for (auto [key, m] : named_dynamics(models.dynamics, models.ensemble))
    evaluation_mode(m);
  evaluation_mode(models.reward);
  evaluation_mode(models.critics);
  models.plan_on = std::move(plan_on);
  out.controller = make_controller(controller, models, config, /*evaluation=*/true);
  return out;
}

}  // namespace hlt
