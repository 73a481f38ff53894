#include "envs/scripted.h"

#include <map>

#include <fmt/format.h>

#include "hlt/util/error.h"

namespace hlt {

// Factory declarations, one per line of scripted_list.inc.
#define HLT_SCRIPTED(name, env, factory) std::unique_ptr<PolicySource> factory(uint64_t seed);
#include "envs/scripted_list.inc"
#undef HLT_SCRIPTED

namespace {

struct Entry {
  std::string env;
  std::unique_ptr<PolicySource> (*factory)(uint64_t);
};

const std::map<std::string, Entry>& table() {
  static const std::map<std::string, Entry> entries = {
#define HLT_SCRIPTED(name, env, factory) {name, {env, factory}},
#include "envs/scripted_list.inc"
#undef HLT_SCRIPTED
  };
  return entries;
}

}  // namespace

std::unique_ptr<PolicySource> make_scripted_policy(const std::string& name, const std::string& env,
                                                   uint64_t seed) {
  const auto it = table().find(name);
  check(it != table().end(), "unknown scripted policy '{}'; known: {}", name,
        fmt::join(scripted_policy_names(), ", "));
  check(it->second.env == env, "scripted policy '{}' drives {}, not {}", name, it->second.env, env);
  return it->second.factory(seed);
}

std::vector<std::string> scripted_policy_names() {
  std::vector<std::string> names;
  for (const auto& kv : table())
    names.push_back(kv.first);
  return names;
}

}  // namespace hlt
