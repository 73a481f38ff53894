// hlt::Trainer: one training run of any method on any registered environment, with the method's outer loop
// (agents/method_list.inc). The online loop (paper Alg. 1 and 2), per agent step: act with the method's
// controller, step the environment with frame skip, store (s, a, r, s', a', done) in D; once enough
// transitions are stored, each of the method's learners updates on batches of its data. The imitation loop
// (Alg. 3), per iteration: one demonstration into D_exp and D, the learners' updates, one test episode into
// D. It logs episodes (iterations), losses and evaluations to <run>/scalars.csv, writes the resolved config
// to <run>/config.yaml, and checkpoints everything (networks, optimizers, replay buffer, generators,
// counters) atomically to <run>/checkpoint.pt at episode ends, so a killed run resumes and logs exactly what
// an uninterrupted run would have. At the end it writes the networks alone to <run>/final.pt.
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
  // Continues the run in `run_dir` from its last checkpoint. `budget` may raise its budget (budget_key).
  static std::unique_ptr<Trainer> resume(const std::string& run_dir, std::optional<int64_t> budget = {});
  // The config key that --steps sets: train.agent_steps, or imitation.iterations for an imitation method.
  static std::string budget_key(const Config& config);
  ~Trainer();

  // Trains until the budget is reached; `progress` draws a progress bar on stderr.
  void run(bool progress);
  const Config& config() const;
  const std::string& run_dir() const;
  // Where the run stands (what its closing line reports).
  struct Summary {
    int64_t agent_steps = 0, env_steps = 0;
    double last_eval = 0, last_return = 0;  // NaN if none in this session
    int64_t iterations = -1;                // demonstrations so far (imitation loop), -1 for the online loop
  };
  Summary summary() const;

  // File names inside a run directory.
  static constexpr const char* kConfigFile = "config.yaml";
  static constexpr const char* kLogFile = "scalars.csv";
  static constexpr const char* kCheckpointFile = "checkpoint.pt";  // resumable state, at episode ends
  static constexpr const char* kFinalFile = "final.pt";            // the networks when the run stopped
  // eval.trace: every evaluation's episodes step by step, step<env steps>[_<component>].csv (TrajectoryCsv).
  static constexpr const char* kEvalTraceDir = "eval_traces";

 private:
  struct Impl;
  explicit Trainer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hlt
