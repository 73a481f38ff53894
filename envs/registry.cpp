#include "envs/registry.h"

#include <functional>
#include <map>

#include "hlt/util/error.h"

namespace hlt {

// Factory declarations, one per line of env_list.inc.
#define HLT_ENV(name, factory) std::unique_ptr<Env> factory();
#include "envs/env_list.inc"
#undef HLT_ENV

namespace {

const std::map<std::string, std::function<std::unique_ptr<Env>()>>& factories() {
  static const std::map<std::string, std::function<std::unique_ptr<Env>()>> table = {
#define HLT_ENV(name, factory) {name, factory},
#include "envs/env_list.inc"
#undef HLT_ENV
  };
  return table;
}

}  // namespace

std::unique_ptr<Env> make_env(const std::string& name) {
  auto it = factories().find(name);
  check(it != factories().end(), "unknown environment '{}'; known environments: {}", name,
        fmt::join(env_names(), ", "));
  return it->second();
}

std::unique_ptr<Env> make_env_like(const Env& env) {
  std::unique_ptr<Env> copy = make_env(env.name());
  if (const auto* skip = dynamic_cast<const FrameSkip*>(&env))
    copy = std::make_unique<FrameSkip>(std::move(copy), skip->frame_skip());
  return copy;
}

std::vector<std::string> env_names() {
  std::vector<std::string> names;
  for (const auto& kv : factories())
    names.push_back(kv.first);
  return names;
}

}  // namespace hlt
