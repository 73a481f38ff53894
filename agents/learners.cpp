// The learner registry, and SAC, the model learner and behaviour cloning seen as Learners: their
// factories (which read the config) and the conversion of their loss structs to log tags.
#include <functional>
#include <map>

#include "agents/behaviour_cloning.h"
#include "agents/learner.h"
#include "agents/model_learner.h"
#include "agents/sac.h"
#include "hlt/util/error.h"

namespace hlt {

#define HLT_LEARNER(name, factory) std::unique_ptr<Learner> factory(LearnerContext&);
#include "agents/learner_list.inc"
#undef HLT_LEARNER

namespace {

using Factory = std::function<std::unique_ptr<Learner>(LearnerContext&)>;

const std::map<std::string, Factory>& learners() {
  static const std::map<std::string, Factory> table = {
#define HLT_LEARNER(name, factory) {name, factory},
#include "agents/learner_list.inc"
#undef HLT_LEARNER
  };
  return table;
}

}  // namespace

std::unique_ptr<Learner> make_learner(const std::string& name, LearnerContext& context) {
  auto it = learners().find(name);
  check(it != learners().end(), "unknown learner '{}'; known learners: {}", name,
        fmt::join(learner_names(), ", "));
  return it->second(context);
}

std::vector<std::string> learner_names() {
  std::vector<std::string> names;
  for (const auto& kv : learners())
    names.push_back(kv.first);
  return names;
}

namespace {
// A network's options get the environment's declared observation ranges as their input normalisation.
template <typename Options>
void set_input_normalisation(const LearnerContext& context, const char* key, Options& o) {
  check(context.observation_scale.has_value(),
        "{}=true: environment '{}' declares no observation ranges to normalise by", key,
        context.config.get_string("env"));
  const ObservationScale& s = *context.observation_scale;
  o.input_offset.assign(s.offset.data(), s.offset.data() + s.offset.size());
  o.input_scale.assign(s.scale.data(), s.scale.data() + s.scale.size());
  o.input_reference.assign(s.reference.data(), s.reference.data() + s.reference.size());
}
}  // namespace

GaussianPolicy& config_policy(LearnerContext& context) {
  if (!context.models.policy) {
    const Config& c = context.config;
    GaussianPolicyOptions po;
    po.state_dim = context.state_dim;
    po.action_dim = context.action_dim;
    po.hidden = c.get_int_list("policy.hidden");
    po.mean_activation = parse_activation(c.get_string("policy.activation"));
    if (c.get_bool("policy.normalize_inputs"))
      set_input_normalisation(context, "policy.normalize_inputs", po);
    context.models.policy = GaussianPolicy(po);
  }
  return context.models.policy;
}

// SAC ------------------------------------------------------------------------------------------------

NamedLosses Sac::train(const Batch& batch) {
  const SacLosses l = update(batch);
  NamedLosses out = {
      {"loss/critic", l.critic}, {"loss/actor", l.actor}, {"sac/alpha", l.alpha}, {"sac/entropy", l.entropy}};
  if (bc_weight() > 0) out.push_back({"loss/sac_bc", l.bc});
  return out;
}

std::unique_ptr<Learner> make_sac_learner(LearnerContext& context) {
  const Config& c = context.config;
  // The policy first, then the critics: the order in which they draw their initial weights.
  GaussianPolicy policy = config_policy(context);
  SacOptions so;
  so.gamma = c.get_double("sac.gamma");
  so.tau = c.get_double("sac.tau");
  so.q_lr = so.policy_lr = so.alpha_lr = c.get_double("sac.lr");
  if (c.get_double("sac.policy_lr") > 0) so.policy_lr = c.get_double("sac.policy_lr");
  if (c.get_double("sac.alpha_lr") > 0) so.alpha_lr = c.get_double("sac.alpha_lr");
  so.q_hidden = c.get_int_list("sac.q_hidden");
  so.initial_alpha = c.get_double("sac.initial_alpha");
  so.bc_weight = c.get_double("sac.bc_weight");
  so.seed = context.seed;
  auto sac = std::make_unique<Sac>(policy, context.state_dim, context.action_dim, so);
  context.models.critics = sac->critics();
  return sac;
}

// Model learner ----------------------------------------------------------------------------------------

NamedLosses ModelLearner::train(const Batch& batch) {
  const ModelLosses l = update(batch);
  return {{"loss/dynamics", l.dynamics}, {"loss/reward", l.reward}};
}

std::unique_ptr<Learner> make_model_learner(LearnerContext& context) {
  const Config& c = context.config;
  LearnedModels& m = context.models;
  const int64_t n = context.state_dim, a = context.action_dim;
  const bool normalize = c.get_bool("model.normalize_inputs");
  if (!m.dynamics) {
    DynamicsModelOptions o;
    o.state_dim = n;
    o.action_dim = a;
    o.hidden = c.get_int("model.hidden");
    o.activation = parse_activation(c.get_string("model.activation"));
    if (normalize) set_input_normalisation(context, "model.normalize_inputs", o);
    m.dynamics = DynamicsModel(o);
  }
  if (!m.reward) {
    RewardModelOptions o;
    o.state_dim = n;
    o.action_dim = a;
    o.hidden = c.get_int("model.reward_hidden");
    o.reads_next_state = c.get_string("model.reward_input") == "next_state";
    if (normalize) set_input_normalisation(context, "model.normalize_inputs", o);
    m.reward = RewardModel(o);
  }
  // The ensemble's other members after both models, so that a single model draws what it always drew.
  const int64_t members = c.get_int("model.ensemble");
  while (static_cast<int64_t>(m.ensemble.size()) + 1 < members) {
    DynamicsModelOptions o = m.dynamics->options();
    m.ensemble.push_back(DynamicsModel(o));
  }
  ModelLearnerOptions mo;
  mo.lr = c.get_double("model.lr");
  mo.reward_gamma = c.get_double("model.reward_gamma");
  mo.reward_weight = c.get_double("model.reward_weight");
  mo.weight_decay = c.get_double("model.weight_decay");
  mo.rollout_steps = c.get_int("model.rollout_steps");
  mo.hard_mining = c.get_int("model.hard_mining");
  return std::make_unique<ModelLearner>(m.dynamics, m.reward, mo, m.ensemble);
}

// Behaviour cloning --------------------------------------------------------------------------------------

NamedLosses BehaviourCloning::train(const Batch& batch) {
  return {{"loss/bc", update(batch.states, batch.actions)}};
}

std::unique_ptr<Learner> make_bc_learner(LearnerContext& context) {
  BehaviourCloningOptions o;
  o.lr = context.config.get_double("bc.lr");
  o.censor_saturated = context.config.get_bool("bc.censor_saturated");
  o.weight_decay = context.config.get_double("bc.weight_decay");
  o.input_noise = context.config.get_double("bc.input_noise");
  return std::make_unique<BehaviourCloning>(config_policy(context), o);
}

}  // namespace hlt
