// Fixed policies named by a string, as the tools and the imitation loop's demonstrator take them: the
// ones of envs/rollout.h ("zero", "random", "constant:V[,...]", "scripted:NAME" for an environment's scripted
// expert), "expert:PATH" (ExpertPolicy) and "oracle:H,K[,LAMBDA[,NOISE]]" (OraclePolicy: MPPI on a copy of
// the environment, which must then outlive the policy).
// Trained policies ("checkpoint:PATH") are loaded by agents/saved_policy.h, which also needs to know the
// frame skip before the environment is built.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "envs/env.h"
#include "envs/rollout.h"

namespace hlt {

// Throws hlt::Error for an unknown spec, an unreadable expert, or an expert whose sizes are not `env`'s;
// `what` names the setting in the message (e.g. "--policy"). `seed` seeds the random policy.
std::unique_ptr<PolicySource> make_fixed_policy(const std::string& spec, const Env& env, uint64_t seed,
                                                const std::string& what);

}  // namespace hlt
