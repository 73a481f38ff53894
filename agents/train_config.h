// The settings of a training run: every key hlt_train accepts, with types, defaults, ranges and docs.
// Per-environment defaults (the paper's hyper-parameters) live in experiments/configs/<env>.yaml.
#pragma once

#include <string>

#include "hlt/util/config.h"

namespace hlt {

Config make_train_config();

// The shipped per-environment defaults (<config_dir>/<env>.yaml), the per-method overlay
// (<config_dir>/methods/<method>.yaml) and a method's settings for one environment
// (<config_dir>/methods/<method>/<env>.yaml), each loaded into `config` if the file exists. hlt_train
// applies them in this order, after the declared defaults and before --config and the flags.
void load_env_defaults(Config& config, const std::string& config_dir, const std::string& env);
void load_method_overlay(Config& config, const std::string& config_dir, const std::string& method,
                         const std::string& env);

}  // namespace hlt
