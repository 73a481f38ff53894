// hlt_model_fit: fits a config's learned models (model.* keys: the dynamics and reward models and their
// learner) to recorded transitions and scores them, as they train, on those and on other recordings: the
// dynamics model against predicting "no change" (ModelCheck), the reward model (on the recorded states)
// against predicting the recordings' mean reward. A model setting can then be judged on the data a task
// gives it, in seconds, without a training run around it.
//
//   hlt_model_fit --env ENV --train FILE.hltd [--train ...] --test FILE.hltd [--test ...]
//                 [--updates N] [--report-every N] [--seed S] [--method M] [--config FILE] [key=value ...]
//
// The recordings come from `hlt_rollout --demos FILE` (any policy). Settings resolve as hlt_train's:
// declared defaults, experiments/configs/<env>.yaml, the method's overlay (if --method), --config, then the
// overrides.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <torch/torch.h>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <CLI/CLI.hpp>

#include "agents/demonstrations.h"
#include "agents/learner.h"
#include "agents/model_check.h"
#include "agents/train_config.h"
#include "envs/registry.h"
#include "experiments/cli_checks.h"
#include "hlt/core/runtime.h"
#include "hlt/data/replay_buffer.h"
#include "hlt/util/error.h"
#include "hlt/util/main_guard.h"

namespace hlt {
namespace {

struct Recordings {
  std::vector<Demonstrations> files;
  int64_t transitions = 0;
};

// Every file must be of `env` with these sizes and at `frame_skip` (0: the first file's).
Recordings load_all(const std::vector<std::string>& paths, const std::string& env, int n, int m,
                    int frame_skip = 0) {
  Recordings r;
  for (const std::string& path : paths) {
    Demonstrations d = Demonstrations::load(path);
    if (frame_skip == 0) frame_skip = d.frame_skip();
    d.check_matches(env, n, m, frame_skip);
    r.transitions += d.transitions();
    r.files.push_back(std::move(d));
  }
  return r;
}

// Every transition into `check`, and into `buffer` if given; the next action (for the reward model's TD
// target) is the next step's, or the step's own at an episode's end.
void fill(const Recordings& r, ModelCheck& check, ReplayBuffer* buffer = nullptr) {
  for (const Demonstrations& d : r.files) {
    for (const std::vector<DemoStep>& episode : d.episodes()) {
      for (size_t t = 0; t < episode.size(); ++t) {
        const DemoStep& s = episode[t];
        check.add(s.observation, s.action, s.next_observation);
        if (!buffer) continue;
        const Eigen::VectorXd& next_action = t + 1 < episode.size() ? episode[t + 1].action : s.action;
        buffer->add(s.observation.data(), s.action.data(), s.reward, s.next_observation.data(),
                    next_action.data(), s.terminated);
      }
    }
  }
}

// The recorded steps as tensors, for scoring the reward model.
struct RewardSet {
  torch::Tensor states, actions, next_states, rewards;
};

RewardSet reward_set(const Recordings& r, int n, int m) {
  std::vector<float> s, a, s2, rw;
  for (const Demonstrations& d : r.files)
    for (const std::vector<DemoStep>& episode : d.episodes())
      for (const DemoStep& step : episode) {
        s.insert(s.end(), step.observation.data(), step.observation.data() + n);
        a.insert(a.end(), step.action.data(), step.action.data() + m);
        s2.insert(s2.end(), step.next_observation.data(), step.next_observation.data() + n);
        rw.push_back(static_cast<float>(step.reward));
      }
  const int64_t k = static_cast<int64_t>(rw.size());
  auto tensor = [](std::vector<float>& v, int64_t rows, int64_t cols) {
    return torch::from_blob(v.data(), {rows, cols}, torch::kFloat32).clone();
  };
  return {tensor(s, k, n), tensor(a, k, m), tensor(s2, k, n), tensor(rw, k, 1)};
}

// rms(predicted - recorded reward) / rms(recorded - its mean): 0 exact, 1 no better than the mean. The
// model reads the recorded states (for r(s', a), the recorded next state): its own error, apart from the
// dynamics model's.
double reward_error_ratio(RewardModelImpl& reward, const RewardSet& set) {
  torch::InferenceMode guard;
  const torch::Tensor predicted = reward.predict(set.states, set.actions, set.next_states);
  const double error = (predicted - set.rewards).square().mean().sqrt().item<double>();
  const double spread = (set.rewards - set.rewards.mean()).square().mean().sqrt().item<double>();
  return error / spread;
}

std::string score_text(const ModelScore& s) {
  return fmt::format("{:.3f} (better in {} of {})", s.error_ratio, s.better, s.error_rms.size());
}

int run(int argc, char** argv) {
  CLI::App app{
      "Fits a config's dynamics and reward models to recorded transitions (hlt_rollout --demos) and scores "
      "the dynamics model on them and on other recordings against predicting 'no change'."};
  std::string env_name, method, config_file;
  std::vector<std::string> train_files, test_files, overrides;
  int64_t updates = 5000, report_every = 500;
  uint64_t seed = 0;
  app.add_option("--env", env_name, "Environment the recordings were made on")->required();
  app.add_option("--train", train_files, "Recordings to fit to (.hltd; repeatable)")->required();
  app.add_option("--test", test_files, "Recordings to score on (.hltd; repeatable)")->required();
  app.add_option("--updates", updates, "Model updates (batches of train.batch_size)")
      ->check(CLI::Range(int64_t{1}, int64_t{100000000}));
  app.add_option("--report-every", report_every, "Score every this many updates")
      ->check(CLI::Range(int64_t{1}, int64_t{100000000}));
  app.add_option("--seed", seed, "Seed of the networks' initial weights and of the batches");
  app.add_option("--method", method, "Method whose config overlay to apply (experiments/configs/methods)");
  app.add_option("--config", config_file, "YAML config file applied after the defaults");
  app.add_option("overrides", overrides, "key=value config overrides, e.g. model.weight_decay=0.001");
  if (auto code = parse_command_line(app, argc, argv)) return *code;
  check_finite_flags(app);

  Config config = make_train_config();
  config.set("env", env_name, "--env");
  load_env_defaults(config, HLT_CONFIG_DIR, env_name);
  if (!method.empty()) {
    config.set("method", method, "--method");
    load_method_overlay(config, HLT_CONFIG_DIR, method);
  }
  if (!config_file.empty()) config.load_file(config_file);
  for (const std::string& o : overrides)
    config.apply_override(o);
  set_torch_threads(static_cast<int>(config.get_int("threads")));
  seed_torch(seed);

  const std::unique_ptr<Env> env = make_env(env_name);
  const int n = env->observation_dim(), m = env->action_dim();
  const Recordings train = load_all(train_files, env_name, n, m);
  const int frame_skip = train.files.front().frame_skip();
  const Recordings test = load_all(test_files, env_name, n, m, frame_skip);
  check(train.transitions > 0 && test.transitions > 0,
        "--train and --test need at least one transition each");

  ReplayBuffer buffer(train.transitions, n, m, seed);
  ModelCheck train_check, test_check;
  fill(train, train_check, &buffer);
  fill(test, test_check);

  LearnedModels models;
  LearnerContext context{config, n, m, seed, models, env->observation_scale()};
  const std::unique_ptr<Learner> learner = make_learner("models", context);
  const int64_t batch_size = config.get_int("train.batch_size");
  fmt::print(
      "fitting the models of {} (model.hidden {}, model.activation {}, model.lr {}, normalised inputs "
      "{}) to {} transitions, scoring on {}; frame skip {}\n",
      env_name, config.get_int("model.hidden"), config.get_string("model.activation"),
      config.get_double("model.lr"), config.get_bool("model.normalize_inputs"), train.transitions,
      test.transitions, frame_skip);
  const RewardSet train_rewards = reward_set(train, n, m), test_rewards = reward_set(test, n, m);
  fmt::print(
      "updates | dynamics loss | error / 'no change' on --train | on --test | reward error / spread on "
      "--train | on --test (model.reward_input {})\n",
      config.get_string("model.reward_input"));
  ModelScore on_test;
  for (int64_t u = 1; u <= updates; ++u) {
    const NamedLosses losses = learner->train(buffer.sample(batch_size));
    if (u % report_every == 0 || u == updates) {
      const ModelScore on_train = train_check.score(*models.dynamics, *env);
      on_test = test_check.score(*models.dynamics, *env);
      fmt::print("{} | {:.4g} | {} | {} | {:.3f} | {:.3f}\n", u, losses.front().value, score_text(on_train),
                 score_text(on_test), reward_error_ratio(*models.reward, train_rewards),
                 reward_error_ratio(*models.reward, test_rewards));
    }
  }
  // The last report's scores (u == updates always reports).
  fmt::print("on --test, per component:\n  rms error  {:.4g}\n  rms change {:.4g}\n",
             fmt::join(on_test.error_rms, " "), fmt::join(on_test.change_rms, " "));
  return 0;
}

}  // namespace
}  // namespace hlt

int main(int argc, char** argv) {
  return hlt::guarded_main("hlt_model_fit", [&] { return hlt::run(argc, argv); });
}
