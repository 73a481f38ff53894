// Loading a trained policy from an hlt_train checkpoint as a PolicySource for tools (hlt_rollout). The
// checkpoint carries the policy's architecture, so no config is needed; the source acts with the policy's
// mean action.
#pragma once

#include <memory>
#include <string>

#include "envs/rollout.h"
#include "hlt/nn/gaussian_policy.h"

namespace hlt {

struct SavedPolicy {
  std::unique_ptr<PolicySource> source;
  std::string env;                // the environment it was trained on
  std::string method;             // the method that trained it
  int frame_skip = 1;             // the frame skip it was trained with
  GaussianPolicyOptions options;  // the policy as rebuilt, its input normalisation included
};

// Throws hlt::Error if the file is not an hlt checkpoint or holds no policy (e.g. a baseline without one).
SavedPolicy load_saved_policy(const std::string& checkpoint_path);

}  // namespace hlt
