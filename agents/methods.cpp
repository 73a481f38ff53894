#include "agents/methods.h"

#include <functional>
#include <map>

#include "hlt/control/action_sampler.h"
#include "hlt/control/deterministic_hybrid.h"
#include "hlt/control/policy_controller.h"
#include "hlt/control/stochastic_hybrid.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

const std::vector<MethodSpec>& methods() {
  static const std::vector<MethodSpec> table = {
#define HLT_LEARNERS(...)   \
  std::vector<LearnerUse> { \
    __VA_ARGS__             \
  }
#define HLT_METHOD(name, loop, controller, planner, learners, description) \
  {name, loop, controller, planner, learners, description},
#include "agents/method_list.inc"
#undef HLT_METHOD
#undef HLT_LEARNERS
  };
  return table;
}

void require(bool present, const std::string& controller, const char* what) {
  check(present, "controller '{}' needs a {}", controller, what);
}

StochasticHybridOptions stochastic_options(const Config& c) {
  StochasticHybridOptions o;
  o.horizon = c.get_int("planner.horizon");
  o.samples = c.get_int("planner.samples");
  o.lambda = c.get_double("planner.lambda");
  o.density_in_weights = c.get_bool("planner.density_in_weights");
  o.min_ess = c.get_double("planner.min_ess_fraction") * static_cast<double>(o.samples);
  o.clamp_to_domain = c.get_bool("planner.clamp_to_data");
  o.terminal_value_weight = c.get_double("planner.terminal_value");
  o.average_before_squash = c.get_bool("planner.average_before_squash");
  return o;
}

// `with_policy`: the hybrid (which uses deterministic.action_rule); the model-based baseline keeps the exact
// rule (no policy: mu = 0, Sigma = I).
DeterministicHybridOptions deterministic_options(const Config& c, bool evaluation, bool with_policy) {
  DeterministicHybridOptions o;
  o.horizon = c.get_int("planner.horizon");
  o.clamp_adjoint = c.get_bool("deterministic.clamp_adjoint");
  o.exploration_decay = c.get_double("deterministic.exploration_decay");
  o.explore = !evaluation;
  if (with_policy) {
    if (c.get_string("deterministic.exploration") == "policy")
      o.exploration = DeterministicExploration::kPolicy;
    const std::string rule = c.get_string("deterministic.action_rule");
    if (rule == "bounded") o.rule = DeterministicActionRule::kBounded;
    if (rule == "squashed") o.rule = DeterministicActionRule::kBoundedSquashed;
  }
  return o;
}

// What a stochastic planner rolls out on: models.plan_on if set, else the learned models.
std::shared_ptr<RolloutModel> rollout_model(const LearnedModels& m, const StochasticHybridOptions& o,
                                            const Config& c, const std::string& controller) {
  if (m.plan_on) {
    check(m.policy.is_empty() || m.plan_on->dtype() == m.policy->parameters().front().scalar_type(),
          "{}: the model it plans on and the policy differ in dtype", controller);
    return m.plan_on;
  }
  require(!m.dynamics.is_empty() && !m.reward.is_empty(), controller, "dynamics and reward model");
  EnsembleOptions ensemble;
  ensemble.members = m.ensemble;
  ensemble.disagreement_penalty = c.get_double("planner.disagreement_penalty");
  return std::make_shared<LearnedRolloutModel>(m.dynamics, m.reward, o.clamp_to_domain, std::move(ensemble));
}

// The deterministic planners differentiate one model; an ensemble's others would be trained and ignored.
void require_single_model(const LearnedModels& m, const char* controller) {
  check(m.ensemble.empty(),
        "controller '{}' plans on one dynamics model: model.ensemble must be 1 (the stochastic planners "
        "use an ensemble)",
        controller);
}

std::unique_ptr<Controller> make_policy_controller(const LearnedModels& m, const Config&, bool evaluation) {
  require(!m.policy.is_empty(), "policy", "policy");
  return std::make_unique<PolicyController>(m.policy, evaluation);
}

std::unique_ptr<Controller> make_stochastic_hybrid(const LearnedModels& m, const Config& c, bool) {
  require(!m.policy.is_empty(), "stochastic_hybrid", "policy");
  std::shared_ptr<ActionSampler> sampler = std::make_shared<PolicySampler>(
      m.policy, c.get_bool("planner.density_tanh_correction"), c.get_bool("planner.mean_rollout"));
  StochasticHybridOptions o = stochastic_options(c);
  const int64_t plan_samples = c.get_int("planner.plan_samples");
  check(plan_samples > 0 || !c.get_bool("planner.plan_noise_from_policy"),
        "planner.plan_noise_from_policy=true scales the plan samples' noise, but planner.plan_samples is 0");
  if (plan_samples > 0) {
    // planner.samples rollouts from the policy plus plan_samples around the warm-started plan.
    auto noise = std::make_shared<FilteredNoiseSampler>(
        c.get_double("mppi.sigma"), c.get_double("mppi.filter"),
        c.get_bool("planner.plan_noise_from_policy") ? std::optional<GaussianPolicy>(m.policy)
                                                     : std::nullopt);
    sampler = std::make_shared<MixtureSampler>(sampler, noise, plan_samples, m.policy,
                                               c.get_bool("planner.density_tanh_correction"));
    o.samples += plan_samples;
    // Without the prior the weights are exp(J / lambda) alone.
    if (!c.get_bool("planner.plan_prior")) o.density_in_weights = false;
  }
  TerminalValue value;
  if (o.terminal_value_weight > 0) {
    require(!m.critics.is_empty(), "stochastic_hybrid with planner.terminal_value > 0",
            "trained SAC critic (a run's checkpoint.pt holds it, its final.pt does not)");
    // The critic at the policy's own (mean) action: the value of following the policy after the horizon.
    value = [policy = m.policy, critics = m.critics](const at::Tensor& s) mutable {
      const at::Tensor x = s.to(critics->weights[0].scalar_type());
      return critics->min_q(x, policy->mean_action(x));
    };
  }
  return std::make_unique<StochasticHybrid>(sampler, rollout_model(m, o, c, "stochastic_hybrid"), o, m.policy,
                                            "stochastic_hybrid", std::move(value));
}

std::unique_ptr<Controller> make_mppi(const LearnedModels& m, const Config& c, bool) {
  auto sampler =
      std::make_shared<FilteredNoiseSampler>(c.get_double("mppi.sigma"), c.get_double("mppi.filter"));
  // The baseline has no critic: it plans with the models alone.
  StochasticHybridOptions o = stochastic_options(c);
  o.terminal_value_weight = 0;
  return std::make_unique<StochasticHybrid>(sampler, rollout_model(m, o, c, "mppi"), o, nullptr, "mppi");
}

std::unique_ptr<Controller> make_deterministic_hybrid(const LearnedModels& m, const Config& c,
                                                      bool evaluation) {
  require(!m.policy.is_empty(), "deterministic_hybrid", "policy");
  require(!m.dynamics.is_empty() && !m.reward.is_empty(), "deterministic_hybrid",
          "dynamics and reward model");
  require_single_model(m, "deterministic_hybrid");
  return std::make_unique<DeterministicHybrid>(
      m.policy, m.dynamics, m.reward, deterministic_options(c, evaluation, true), "deterministic_hybrid");
}

std::unique_ptr<Controller> make_mpc_deterministic(const LearnedModels& m, const Config& c, bool evaluation) {
  require(!m.dynamics.is_empty() && !m.reward.is_empty(), "mpc_deterministic", "dynamics and reward model");
  require_single_model(m, "mpc_deterministic");
  return std::make_unique<DeterministicHybrid>(
      nullptr, m.dynamics, m.reward, deterministic_options(c, evaluation, false), "mpc_deterministic");
}

using Factory = std::function<std::unique_ptr<Controller>(const LearnedModels&, const Config&, bool)>;

const std::map<std::string, Factory>& controllers() {
  static const std::map<std::string, Factory> table = {
#define HLT_CONTROLLER(name, factory) {name, factory},
#include "agents/controller_list.inc"
#undef HLT_CONTROLLER
  };
  return table;
}

}  // namespace

const MethodSpec& find_method(const std::string& name) {
  for (const auto& m : methods()) {
    if (m.name == name) return m;
  }
  throw Error(fmt::format("unknown method '{}'; known methods: {}", name, fmt::join(method_names(), ", ")));
}

std::vector<std::string> method_names() {
  std::vector<std::string> names;
  for (const auto& m : methods())
    names.push_back(m.name);
  return names;
}

std::unique_ptr<Controller> make_controller(const std::string& name, const LearnedModels& models,
                                            const Config& config, bool evaluation) {
  auto it = controllers().find(name);
  check(it != controllers().end(), "unknown controller '{}'; known controllers: {}", name,
        fmt::join(controller_names(), ", "));
  return it->second(models, config, evaluation);
}

std::vector<std::pair<std::string, DynamicsModel>> named_dynamics(const DynamicsModel& first,
                                                                  const std::vector<DynamicsModel>& others) {
  std::vector<std::pair<std::string, DynamicsModel>> out;
  if (first.is_empty()) return out;
  out.emplace_back("dynamics", first);
  for (size_t i = 0; i < others.size(); ++i)
    out.emplace_back(fmt::format("dynamics_member{}", i + 1), others[i]);
  return out;
}

std::vector<std::string> controller_names() {
  std::vector<std::string> names;
  for (const auto& kv : controllers())
    names.push_back(kv.first);
  return names;
}

}  // namespace hlt
