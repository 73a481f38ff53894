#include "agents/policy_spec.h"

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
  if (spec.rfind(OraclePolicy::kPrefix, 0) == 0)
    return std::make_unique<OraclePolicy>(
        env, OraclePolicy::parse(spec.substr(std::string(OraclePolicy::kPrefix).size())), seed);
  return make_policy_for(spec, env, seed);
}

}  // namespace hlt
