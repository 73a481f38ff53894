// The environment registry: environments are created by name. The list lives in envs/env_list.inc, one
// line per environment, so adding one is a new source file plus one line there.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "envs/env.h"

namespace hlt {

// Creates the environment registered as `name`; throws hlt::Error listing the known names otherwise.
std::unique_ptr<Env> make_env(const std::string& name);
std::vector<std::string> env_names();
// A fresh environment built as `env` was: the same registered name, frame-skipped as `env` is, so that
// `env`'s snapshots (save_state) restore into it. For planners that simulate ahead on a copy.
std::unique_ptr<Env> make_env_like(const Env& env);

}  // namespace hlt
