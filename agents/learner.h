// hlt::Learner: one trainable part of a method (SAC, the model learner, behaviour cloning). It takes one
// gradient step on a batch of transitions and reports its losses by log tag, and it checkpoints its own
// training state (optimizers, critics, generators) under keys it owns. The networks it trains are shared
// with the controllers (LearnedModels), so the trainer checkpoints those once for every learner.
//
// Learners are registered by name in agents/learner_list.inc; a method (agents/method_list.inc) names the
// learners it trains, the data source each samples from and the config key of its update count.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "agents/methods.h"
#include "envs/env.h"
#include "hlt/data/replay_buffer.h"
#include "hlt/util/config.h"

namespace hlt {

class CheckpointWriter;
class CheckpointReader;

// One loss of an update, by the tag it is logged under (e.g. "loss/critic"). Tags are string literals.
struct NamedLoss {
  const char* tag;
  double value;
};
using NamedLosses = std::vector<NamedLoss>;

class Learner {
 public:
  virtual ~Learner() = default;
  // For messages ("SAC", "model", "behaviour cloning").
  virtual const char* learner_name() const = 0;
  // One gradient step on `batch`; the same tags in the same order at every call.
  virtual NamedLosses train(const Batch& batch) = 0;
  // The batches it takes: single transitions (1) or sequences of this many consecutive ones (Batch).
  virtual int64_t sequence_steps() const { return 1; }
  // Its batches hold this many times train.batch_size transitions (or sequences), among which it chooses
  // what it trains on (1: it trains on all of them).
  virtual int64_t batch_multiple() const { return 1; }
  // Starts its optimizer afresh (moments forgotten, parameters kept). The imitation loop calls it before an
  // iteration's updates where the config asks (imitation.restart_model_optimizer); no-op by default.
  virtual void restart_optimizer() {}
  // Everything the learner needs to continue exactly, except the shared networks.
  virtual void save_training_state(CheckpointWriter& writer) const = 0;
  virtual void load_training_state(CheckpointReader& reader) = 0;
};

// What a learner's factory gets: the config, the sizes, the seed of the learner's own generator, and the
// shared networks, to which it adds the ones it trains (if they are not there yet).
struct LearnerContext {
  const Config& config;
  int64_t state_dim = 0, action_dim = 0;
  uint64_t seed = 0;
  LearnedModels& models;
  // The environment's declared observation ranges, if any (policy.normalize_inputs and
  // model.normalize_inputs need them).
  std::optional<ObservationScale> observation_scale = std::nullopt;
};

// Builds the learner registered as `name`; throws hlt::Error listing the known learners.
std::unique_ptr<Learner> make_learner(const std::string& name, LearnerContext& context);
std::vector<std::string> learner_names();

// The Gaussian policy of the config's policy.* keys, created in `context.models` if it is not there yet
// (SAC and behaviour cloning both train it).
GaussianPolicy& config_policy(LearnerContext& context);

}  // namespace hlt
