// Scripted policies: hand-written controllers for particular environments (demonstrators for imitation
// learning), registered by name in envs/scripted_list.inc. make_policy_for() in envs/rollout.h gives them to
// every tool that takes a policy spec, as "scripted:NAME".
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "envs/rollout.h"

namespace hlt {

constexpr const char* kScriptedPrefix = "scripted:";

// The scripted policy `name` for environment `env`, its noise drawn from `seed`. Throws hlt::Error listing
// the known names for an unknown one, and naming the right environment when `env` is another.
std::unique_ptr<PolicySource> make_scripted_policy(const std::string& name, const std::string& env,
                                                   uint64_t seed);
std::vector<std::string> scripted_policy_names();

}  // namespace hlt
