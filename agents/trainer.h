// hlt::Trainer: one training run of any method on any registered environment, the outer loop of the
// paper's Alg. 1 and 2. Per agent step: act with the method's controller, step the environment with frame
// skip, store (s, a, r, s', a', done); once enough transitions are stored, SAC and model updates. It logs
// episodes, losses and periodic evaluations to <run>/scalars.csv, writes the resolved config to
// <run>/config.yaml, and checkpoints everything (networks, optimizers, replay buffer, generators, counters)
// atomically to <run>/checkpoint.pt at episode ends, so a killed run resumes and logs exactly what an
// uninterrupted run would have. At the end it writes the networks alone to <run>/final.pt.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "hlt/util/config.h"

namespace hlt {

class Trainer {
 public:
  // A new run in `run_dir`; throws hlt::Error if the directory already holds a run or is not writable.
  static std::unique_ptr<Trainer> create(const Config& config, const std::string& run_dir);
  // Continues the run in `run_dir` from its last checkpoint. `agent_steps` may raise the step budget.
  static std::unique_ptr<Trainer> resume(const std::string& run_dir, std::optional<int64_t> agent_steps = {});
  ~Trainer();

  // Trains until the configured number of agent steps; `progress` draws a progress bar on stderr.
  void run(bool progress);
  const Config& config() const;
  const std::string& run_dir() const;
  // Where the run stands (what its closing line reports).
  struct Summary {
    int64_t agent_steps = 0, env_steps = 0;
    double last_eval = 0, last_return = 0;  // NaN if none in this session
  };
  Summary summary() const;

  // File names inside a run directory.
  static constexpr const char* kConfigFile = "config.yaml";
  static constexpr const char* kLogFile = "scalars.csv";
  static constexpr const char* kCheckpointFile = "checkpoint.pt";  // resumable state, at episode ends
  static constexpr const char* kFinalFile = "final.pt";            // the networks when the run stopped

 private:
  struct Impl;
  explicit Trainer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hlt
