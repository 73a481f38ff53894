// The settings of a training run: every key hlt_train accepts, with types, defaults, ranges and docs.
// Per-environment defaults (the paper's hyper-parameters) live in experiments/configs/<env>.yaml.
#pragma once

#include "hlt/util/config.h"

namespace hlt {

Config make_train_config();

}  // namespace hlt
