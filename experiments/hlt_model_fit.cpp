// hlt_model_fit: fits a config's learned models (model.* keys: the dynamics and reward models and their
// learner) to recorded transitions and scores them, as they train, on those and on other recordings: the
// dynamics model against predicting "no change" (ModelCheck), the reward model (on the recorded states)
// against predicting the recordings' mean reward. A model setting can then be judged on the data a task
// gives it, in seconds, without a training run around it.
//
//   hlt_model_fit --env ENV --train FILE.hltd [--train ...] --test FILE.hltd [--test ...]
//                 [--updates N] [--report-every N] [--horizons K,K...] [--seed S] [--method M]
//                 [--config FILE] [key=value ...]
//
// The recordings come from `hlt_rollout --demos FILE` (any policy). Settings resolve as hlt_train's:
// declared defaults, experiments/configs/<env>.yaml, the method's overlay (if --method), --config, then the
// overrides.
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <sstream>
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

// Open-loop prediction k steps ahead, as a planner's rollout uses the model: from every step t of every
// episode with t + k <= its length, the model rolls the recorded actions a_t .. a_{t+k-1} from o_t (each
// prediction kept inside the model's domain if `clamp`). The error of the predicted o_{t+k} against that of
// predicting o_t ("no change"), pooled over the components in `unit` (0 entries left out), as ModelScore's
// error_ratio is.
double open_loop_ratio(DynamicsModelImpl& model, const Recordings& r, int k, const Eigen::VectorXd& unit,
                       bool clamp) {
  const int n = static_cast<int>(unit.size());
  std::vector<float> start, target;
  std::vector<std::vector<float>> actions(static_cast<size_t>(k));
  for (const Demonstrations& d : r.files)
    for (const std::vector<DemoStep>& episode : d.episodes())
      for (size_t t = 0; t + static_cast<size_t>(k) <= episode.size(); ++t) {
        start.insert(start.end(), episode[t].observation.data(), episode[t].observation.data() + n);
        const Eigen::VectorXd& last = episode[t + static_cast<size_t>(k) - 1].next_observation;
        target.insert(target.end(), last.data(), last.data() + n);
        for (int j = 0; j < k; ++j) {
          const Eigen::VectorXd& a = episode[t + static_cast<size_t>(j)].action;
          actions[static_cast<size_t>(j)].insert(actions[static_cast<size_t>(j)].end(), a.data(),
                                                 a.data() + a.size());
        }
      }
  const int64_t b = static_cast<int64_t>(start.size()) / n;
  if (b == 0) return std::numeric_limits<double>::quiet_NaN();
  torch::InferenceMode guard;
  const torch::Tensor s0 = torch::from_blob(start.data(), {b, n}, torch::kFloat32).clone();
  const torch::Tensor goal = torch::from_blob(target.data(), {b, n}, torch::kFloat32).clone();
  torch::Tensor s = s0;
  for (int j = 0; j < k; ++j) {
    std::vector<float>& a = actions[static_cast<size_t>(j)];
    s = model.forward(s,
                      torch::from_blob(a.data(), {b, static_cast<int64_t>(a.size()) / b}, torch::kFloat32));
    if (clamp && model.has_domain()) s = torch::max(torch::min(s, model.domain_high()), model.domain_low());
  }
  const torch::Tensor inv_unit = torch::from_blob(const_cast<double*>(unit.data()), {n}, torch::kFloat64)
                                     .to(torch::kFloat32)
                                     .reciprocal()
                                     .nan_to_num(0, 0, 0);
  const double error = ((s - goal) * inv_unit).square().sum().item<double>();
  const double change = ((goal - s0) * inv_unit).square().sum().item<double>();
  return std::sqrt(error / change);
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
  std::string horizons_text;
  uint64_t seed = 0;
  app.add_option("--env", env_name, "Environment the recordings were made on")->required();
  app.add_option("--train", train_files, "Recordings to fit to (.hltd; repeatable)")->required();
  app.add_option("--test", test_files, "Recordings to score on (.hltd; repeatable)")->required();
  app.add_option("--updates", updates, "Model updates (batches of train.batch_size)")
      ->check(CLI::Range(int64_t{1}, int64_t{100000000}));
  app.add_option("--report-every", report_every, "Score every this many updates")
      ->check(CLI::Range(int64_t{1}, int64_t{100000000}));
  app.add_option("--horizons", horizons_text,
                 "After fitting, also score open-loop predictions this many steps ahead on --test "
                 "(comma-separated, e.g. 20,60)");
  app.add_option("--seed", seed, "Seed of the networks' initial weights and of the batches");
  app.add_option("--method", method, "Method whose config overlay to apply (experiments/configs/methods)");
  app.add_option("--config", config_file, "YAML config file applied after the defaults");
  app.add_option("overrides", overrides, "key=value config overrides, e.g. model.weight_decay=0.001");
  if (auto code = parse_command_line(app, argc, argv)) return *code;
  check_finite_flags(app);
  std::vector<int> horizons;
  if (!horizons_text.empty()) {
    std::stringstream in(horizons_text);
    for (std::string item; std::getline(in, item, ',');) {
      size_t used = 0;
      int k = 0;
      try {
        k = std::stoi(item, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      check(used > 0 && used == item.size() && k >= 1 && k <= 100000,
            "--horizons: '{}' is not a comma-separated list of step counts in [1, 100000]", horizons_text);
      horizons.push_back(k);
    }
  }

  Config config = make_train_config();
  config.set("env", env_name, "--env");
  load_env_defaults(config, HLT_CONFIG_DIR, env_name);
  if (!method.empty()) {
    config.set("method", method, "--method");
    load_method_overlay(config, HLT_CONFIG_DIR, method, env_name);
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
  const bool plain_reward = config.get_double("model.reward_gamma") == 0.0;
  fmt::print(
      "updates | dynamics loss | error / 'no change' on --train | on --test | reward error / spread on "
      "--train | on --test (model.reward_input {}{})\n",
      config.get_string("model.reward_input"), plain_reward ? "" : "; none with model.reward_gamma > 0");
  ModelScore on_test;
  for (int64_t u = 1; u <= updates; ++u) {
    const NamedLosses losses =
        learner->train(buffer.sample(batch_size * learner->batch_multiple(), learner->sequence_steps()));
    if (u % report_every == 0 || u == updates) {
      const ModelScore on_train = train_check.score(*models.dynamics, *env);
      on_test = test_check.score(*models.dynamics, *env);
      // A reward model with a TD target (gamma > 0) fits a discounted sum, not the step's reward: no score.
      const std::string reward_scores =
          plain_reward ? fmt::format("{:.3f} | {:.3f}", reward_error_ratio(*models.reward, train_rewards),
                                     reward_error_ratio(*models.reward, test_rewards))
                       : "- | -";
      fmt::print("{} | {:.4g} | {} | {} | {}\n", u, losses.front().value, score_text(on_train),
                 score_text(on_test), reward_scores);
    }
  }
  // The last report's scores (u == updates always reports).
  fmt::print("on --test, per component:\n  rms error  {:.4g}\n  rms change {:.4g}\n",
             fmt::join(on_test.error_rms, " "), fmt::join(on_test.change_rms, " "));
  if (!horizons.empty()) {
    // In the one-step score's units (the declared ranges, else the spreads of the --test observations).
    const Eigen::VectorXd& unit = on_test.unit;
    const bool clamp = config.get_bool("planner.clamp_to_data");
    fmt::print("open-loop error / 'no change' on --test, k steps ahead (recorded actions{}):\n",
               clamp ? ", predictions kept in the model's domain" : "");
    for (int k : horizons)
      fmt::print("  k {}: {:.3f}\n", k, open_loop_ratio(*models.dynamics, test, k, unit, clamp));
  }
  return 0;
}

}  // namespace
}  // namespace hlt

int main(int argc, char** argv) {
  return hlt::guarded_main("hlt_model_fit", [&] { return hlt::run(argc, argv); });
}
