#include "agents/policy_spec.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "agents/expert_policy.h"
#include "agents/oracle_policy.h"
#include "hlt/util/error.h"

namespace hlt {

std::unique_ptr<PolicySource> make_fixed_policy(const std::string& spec, const Env& env, uint64_t seed,
                                                const std::string& what) {
  if (spec.rfind(ExpertPolicy::kPrefix, 0) == 0) {
    std::unique_ptr<ExpertPolicy> expert;
    try {
      expert = std::make_unique<ExpertPolicy>(spec.substr(std::string(ExpertPolicy::kPrefix).size()));
    } catch (const Error& e) {
      throw Error(fmt::format("{} {}: {}", what, spec, e.what()));
    }
    check(expert->observation_dim() == env.observation_dim() && expert->action_dim() == env.action_dim(),
          "{} {}: the expert maps {} observations to {} actions, {} has {} and {}", what, spec,
          expert->observation_dim(), expert->action_dim(), env.name(), env.observation_dim(),
          env.action_dim());
    return expert;
  }
  try {
    if (spec.rfind(OraclePolicy::kPrefix, 0) == 0)
      return std::make_unique<OraclePolicy>(
          env, OraclePolicy::parse(spec.substr(std::string(OraclePolicy::kPrefix).size())), seed);
    return make_policy_for(spec, env, seed);
  } catch (const Error& e) {
    throw Error(fmt::format("{}: {}", what, e.what()));
  }
}

NoisyPolicy::NoisyPolicy(std::unique_ptr<PolicySource> inner, double sigma, uint64_t seed)
    : inner_(std::move(inner)), sigma_(sigma), rng_(seed) {
  check(inner_ != nullptr, "NoisyPolicy: no policy to add noise to");
  check(std::isfinite(sigma) && sigma >= 0,
        "NoisyPolicy: the noise's standard deviation must be >= 0, got {}", sigma);
}

std::string NoisyPolicy::describe() const {
  return fmt::format("{} with action noise {}", inner_->describe(), sigma_);
}

Eigen::VectorXd NoisyPolicy::act(const Eigen::VectorXd& observation) {
  Eigen::VectorXd action = inner_->act(observation);
  intended_ = inner_->intended_action().value_or(action);
  if (sigma_ == 0) return action;
  std::normal_distribution<double> noise(0.0, sigma_);
  for (Eigen::Index i = 0; i < action.size(); ++i)
    action[i] = std::clamp(action[i] + noise(rng_), -1.0, 1.0);
  return action;
}

}  // namespace hlt
