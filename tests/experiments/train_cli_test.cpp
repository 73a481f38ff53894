// End-to-end tests of hlt_train and hlt_rollout, run as subprocesses: bad input, kill -9 and resume.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <sstream>

#include "agents/saved_policy.h"
#include "agents/train_config.h"
#include "envs/registry.h"
#include "experiments/cli_support.h"
#include "hlt/util/files.h"
#include "hlt/util/scalar_logger.h"

extern char** environ;

namespace hlt {
namespace {
namespace fs = std::filesystem;
using test::comparable_rows;
using test::fresh_dir;
using test::Result;
using test::run;

const std::string kTrain = HLT_TRAIN_BIN;
// A small, fast configuration: pendulum episodes are 50 agent steps with frame skip 4.
const std::string kSmall =
    " --env pendulum --seed 3 train.update_after=64 train.batch_size=32 model.hidden=32 "
    "model.reward_hidden=32"
    " sac.q_hidden=[32,32] planner.samples=8 eval.episodes=1 --no-progress";

// Starts hlt_train with `args` in the background, its output discarded; returns its pid (-1 on failure).
pid_t spawn_train(const std::string& args) {
  std::vector<std::string> words{kTrain};
  std::istringstream split(args);
  for (std::string w; split >> w;)
    words.push_back(w);
  std::vector<char*> argv;
  for (auto& w : words)
    argv.push_back(w.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  pid_t pid = 0;
  const int rc = ::posix_spawn(&pid, kTrain.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  return rc == 0 ? pid : -1;
}

TEST(TrainCli, RejectsBadInputWithClearMessages) {
  Result r = run(kTrain + " --env moonwalk --steps 10 --out " + fresh_dir("bad_env"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find(
                fmt::format("config key 'env' in --env: expected one of: {}", fmt::join(env_names(), ", "))),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("got 'moonwalk'"), std::string::npos) << r.output;
  r = run(kTrain + " --env pendulum --method magic --out " + fresh_dir("bad_method"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("hybrid-stochastic"), std::string::npos) << r.output;
  r = run(kTrain + " --env pendulum planner.samples=-3 --out " + fresh_dir("bad_value"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("'planner.samples'"), std::string::npos) << r.output;
  r = run(kTrain + " --env pendulum planer.samples=3 --out " + fresh_dir("typo"));
  EXPECT_NE(r.output.find("did you mean 'planner.samples'"), std::string::npos) << r.output;
  r = run(kTrain + " --env pendulum --out /proc/hlt_not_writable");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("/proc/hlt_not_writable"), std::string::npos) << r.output;
  r = run(kTrain + " --resume " + fresh_dir("no_such_run"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("no such directory"), std::string::npos) << r.output;
  const std::string bad_yaml = fresh_dir("bad.yaml");
  write_file_atomic(bad_yaml, "train: [1, 2\n");
  r = run(kTrain + " --config " + bad_yaml + " --out " + fresh_dir("bad_yaml_run"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("malformed YAML"), std::string::npos) << r.output;
  // A self-referential alias, a directory as the config file.
  write_file_atomic(bad_yaml, "train: &t\n  x: *t\n");
  r = run(kTrain + " --config " + bad_yaml + " --out " + fresh_dir("alias_run"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("an alias that refers to itself?"), std::string::npos) << r.output;
  r = run(kTrain + " --config " + fs::temp_directory_path().string() + " --out " + fresh_dir("dir_config"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("it is a directory"), std::string::npos) << r.output;
  // --env wins over the file's env (flags come after --config).
  const std::string acrobot_yaml = fresh_dir("acrobot.yaml");
  write_file_atomic(acrobot_yaml, "env: acrobot\n");
  const std::string precedence = fresh_dir("precedence");
  r = run(kTrain + kSmall + " --method sac --config " + acrobot_yaml + " --steps 5 eval.every=0 --out " +
          precedence);
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(read_file(precedence + "/config.yaml").find("env: \"pendulum\""), std::string::npos);
  // The planner's terminal value is SAC's critic: hybrid-stochastic runs with it; a negative weight is
  // refused.
  r = run(kTrain + kSmall +
          " --method hybrid-stochastic --steps 5 eval.every=0 planner.terminal_value=0.5 --out " +
          fresh_dir("terminal_value"));
  EXPECT_EQ(r.code, 0) << r.output;
  r = run(kTrain + kSmall + " --method hybrid-stochastic --steps 5 planner.terminal_value=-1 --out " +
          fresh_dir("negative_terminal_value"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("'planner.terminal_value'"), std::string::npos) << r.output;
  // Replay memory that cannot fit is refused before anything is allocated.
  // (ant: 100M transitions of 74 floats, 29.6 GB; the check is skipped where that much memory is free).
  const Result mem = run("awk '/MemAvailable/ {print $2}' /proc/meminfo");
  if (std::stod(mem.output) < 28e6) {
    r = run(kTrain + " --env ant --steps 1 train.replay_capacity=100000000 --out " + fresh_dir("too_big"));
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("lower train.replay_capacity"), std::string::npos) << r.output;
  }
  // Non-finite numbers in numeric flags of the perception tools.
  r = run(std::string(HLT_PERCEIVE_BIN) + " --input synthetic:3 --fps nan --tags " +
          std::string(HLT_SOURCE_DIR) + "/experiments/configs/perception/sawyer_tags.yaml");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("--fps must be a finite number, got 'nan'"), std::string::npos) << r.output;
}

// The line of a tool's output that starts with `prefix` (after leading spaces), or "".
std::string line_starting(const std::string& output, const std::string& prefix) {
  std::istringstream in(output);
  for (std::string line; std::getline(in, line);) {
    const auto first = line.find_first_not_of(' ');
    if (first != std::string::npos && line.compare(first, prefix.size(), prefix) == 0) return line;
  }
  return "";
}

TEST(PerceptionReport, CameraLoopAndRolloutReportTheSameEpisodesAndTimeEveryStep) {
  const std::string args = " --env block_push_camera --policy random --episodes 2 --max-steps 4 --seed 1";
  const Result loop = run(std::string(HLT_CAMERA_LOOP_BIN) + args);
  const Result rollout = run(std::string(HLT_ROLLOUT_BIN) + args + " --perception");
  ASSERT_EQ(loop.code, 0) << loop.output;
  ASSERT_EQ(rollout.code, 0) << rollout.output;
  for (const Result* r : {&loop, &rollout}) {
    // Two resets and eight steps: ten frames, eight of them timed.
    EXPECT_NE(r->output.find("perception over 10 frames (8 timed control steps)"), std::string::npos)
        << r->output;
    for (const char* row : {"render ", "perceive ", "total ", "total, wall clock "})
      EXPECT_NE(line_starting(r->output, row), "") << row << " missing in\n" << r->output;
  }
  const std::string errors = line_starting(loop.output, "all ");
  EXPECT_NE(errors, "") << loop.output;
  EXPECT_EQ(errors, line_starting(rollout.output, "all ")) << "the two tools ran different episodes";
}

TEST(RolloutCli, ReportsTheTasksSuccess) {
  // The scripted stacking expert stacks (block_stack_test); a task without a criterion prints none.
  Result r =
      run(std::string(HLT_ROLLOUT_BIN) + " --env block_stack --policy scripted:block_stack --episodes 2");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("episode 0: return"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(" success\n"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("success 2 of 2 episodes (100 %)"), std::string::npos) << r.output;
  r = run(std::string(HLT_ROLLOUT_BIN) + " --env block_push --policy zero --episodes 1");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("no success"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("success 0 of 1 episodes (0 %)"), std::string::npos) << r.output;
  r = run(std::string(HLT_ROLLOUT_BIN) + " --env pendulum --policy zero --episodes 1");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.output.find("success"), std::string::npos) << r.output;
}

TEST(RolloutCli, ComparesTheActionsWithAReferencePolicyOnTheVisitedStates) {
  const std::string base =
      std::string(HLT_ROLLOUT_BIN) + " --env pendulum --policy constant:0.5 --max-steps 10";
  Result r = run(base + " --compare constant:-0.25");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("over 10 steps: mean |a - a_ref| 0.7500, rms 0.7500, opposite sign in 100.0 %"),
            std::string::npos)
      << r.output;
  r = run(base + " --compare constant:0.25");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("mean |a - a_ref| 0.2500, rms 0.2500, opposite sign in 0.0 %"), std::string::npos)
      << r.output;
  r = run(base + " --compare nonsense");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.output.find("--compare"), std::string::npos) << r.output;
}

TEST(TrainCli, NeverOverwritesARunAndReportsCorruptCheckpoints) {
  const std::string dir = fresh_dir("existing");
  Result r = run(kTrain + kSmall + " --method sac --steps 60 checkpoint.every=50 eval.every=0 --out " + dir);
  ASSERT_EQ(r.code, 0) << r.output;
  const std::string log_before = read_file(dir + "/scalars.csv");
  // The trained policy runs in hlt_rollout, on its own environment only, and the run plots.
  r = run(std::string(HLT_ROLLOUT_BIN) + " --env pendulum --episodes 2 --policy checkpoint:" + dir +
          "/final.pt");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("frame skip 4"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("mean return"), std::string::npos) << r.output;
  r = run(std::string(HLT_ROLLOUT_BIN) + " --env acrobot --policy checkpoint:" + dir + "/final.pt");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.output.find("trained on pendulum, not acrobot"), std::string::npos) << r.output;
  r = run(std::string("/usr/bin/python3 ") + HLT_PLOT_SCRIPT + " " + dir + " --out " + dir + "/curve.png" +
          " --tags eval/return_mean,train/episode_return");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir + "/curve.png"));
  r = run(kTrain + kSmall + " --method sac --steps 60 --out " + dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("already holds a run"), std::string::npos) << r.output;
  EXPECT_EQ(read_file(dir + "/scalars.csv"), log_before);
  // A truncated checkpoint is reported, not loaded.
  const std::string ckpt = read_file(dir + "/checkpoint.pt");
  write_file_atomic(dir + "/checkpoint.pt", ckpt.substr(0, ckpt.size() / 3));
  r = run(kTrain + " --resume " + dir + " --steps 120 --no-progress");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("corrupt"), std::string::npos) << r.output;
  EXPECT_EQ(read_file(dir + "/scalars.csv"), log_before);
}

TEST(RolloutCli, ModelsPredictEveryStepOfTheRollout) {
  const std::string dir = fresh_dir("models");
  Result r = run(kTrain + kSmall + " --method hybrid-stochastic --steps 60 eval.every=0 --out " + dir);
  ASSERT_EQ(r.code, 0) << r.output;
  r = run(std::string(HLT_ROLLOUT_BIN) + " --env pendulum --episodes 2 --policy random --csv " + dir +
          "/traj.csv --models " + dir + "/final.pt --predictions " + dir + "/pred.csv");
  ASSERT_EQ(r.code, 0) << r.output;
  // Row for row: (episode, step) the same, and each row the loaded models' one-step prediction from that
  // row's observation and action.
  auto lines = [](const std::string& path) {
    std::vector<std::string> out;
    std::istringstream in(read_file(path));
    for (std::string line; std::getline(in, line);)
      out.push_back(line);
    return out;
  };
  const std::vector<std::string> traj = lines(dir + "/traj.csv"), pred = lines(dir + "/pred.csv");
  ASSERT_EQ(traj.size(), pred.size());
  // Two episodes of 50 steps at the run's frame skip 4 (the models predict such a step), and the header.
  ASSERT_EQ(traj.size(), 2u * 50 + 1);
  SavedModels models = load_saved_models(dir + "/final.pt");
  EXPECT_EQ(models.method, "hybrid-stochastic");
  torch::InferenceMode guard;
  for (size_t i : {size_t(1), size_t(37), size_t(100)}) {
    auto fields = [](const std::string& line) {
      std::vector<double> v;
      std::stringstream in(line);
      for (std::string f; std::getline(in, f, ',');)
        v.push_back(std::stod(f));
      return v;
    };
    const std::vector<double> t = fields(traj[i]), p = fields(pred[i]);
    // traj: episode, step, 3 observations, 1 action, reward, done, truncated; pred: episode, step, 3
    // predicted observations, predicted reward.
    ASSERT_EQ(t.size(), 9u);
    ASSERT_EQ(p.size(), 6u);
    EXPECT_EQ(t[0], p[0]);
    EXPECT_EQ(t[1], p[1]);
    const auto s = torch::tensor({t[2], t[3], t[4]}, torch::kFloat32).view({1, 3});
    const auto a = torch::tensor({t[5]}, torch::kFloat32).view({1, 1});
    const auto next = models.dynamics->forward(s, a);
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(p[2 + k], next[0][k].item<double>(), 1e-5) << "row " << i;
    EXPECT_NEAR(p[5], models.reward->forward(s, a).item<double>(), 1e-5) << "row " << i;
  }
  // Refused: without --predictions, at another frame skip, on another environment, and a checkpoint without
  // models (SAC).
  r = run(std::string(HLT_ROLLOUT_BIN) + " --env pendulum --frame-skip 1 --models " + dir +
          "/final.pt --predictions " + dir + "/x.csv");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.output.find("predicts steps of frame skip 4, not 1"), std::string::npos) << r.output;
  r = run(std::string(HLT_ROLLOUT_BIN) + " --env pendulum --models " + dir + "/final.pt");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.output.find("--models and --predictions go together"), std::string::npos) << r.output;
  r = run(std::string(HLT_ROLLOUT_BIN) + " --env acrobot --models " + dir + "/final.pt --predictions " + dir +
          "/x.csv");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.output.find("trained on pendulum, not acrobot"), std::string::npos) << r.output;
  const std::string sac = fresh_dir("models_sac");
  ASSERT_EQ(run(kTrain + kSmall + " --method sac --steps 60 eval.every=0 --out " + sac).code, 0);
  r = run(std::string(HLT_ROLLOUT_BIN) + " --env pendulum --models " + sac + "/final.pt --predictions " +
          sac + "/x.csv");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.output.find("holds no dynamics and reward models"), std::string::npos) << r.output;
}

TEST(RolloutCli, ActsWithARunsPlannerOnItsModelsOrOnTheSimulator) {
  const std::string dir = fresh_dir("controller");
  // checkpoint.pt (written at the first episode's end here) holds what final.pt does not: SAC's critics and
  // the dynamics model's domain; the planner is built from it as the run built it.
  Result r = run(kTrain + kSmall +
                 " --method hybrid-stochastic --steps 60 eval.every=0 checkpoint.every=50 --out " + dir);
  ASSERT_EQ(r.code, 0) << r.output;
  const std::string rollout = std::string(HLT_ROLLOUT_BIN) + " --env pendulum --episodes 2 --max-steps 10";
  const std::string policy = " --policy checkpoint:" + dir + "/checkpoint.pt";
  for (const char* model : {"learned", "simulator", "simulator-dynamics"}) {
    r = run(rollout + policy + " --controller stochastic_hybrid --plan-on " + model);
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("planning on"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("over 2 episodes"), std::string::npos) << r.output;
    // The same seed repeats itself.
    EXPECT_EQ(run(rollout + policy + " --controller stochastic_hybrid --plan-on " + model).output, r.output);
  }
  // --plan-check replays the planner's samples on the simulator: every 5th of 20 steps is 4 calls, and the
  // episodes are those of the same planner unchecked; on the simulator itself the models rank the samples
  // exactly as the replay does.
  r = run(rollout + policy + " --controller stochastic_hybrid --plan-check 5");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("plan check over 4 planning calls"), std::string::npos) << r.output;
  const std::string unchecked = run(rollout + policy + " --controller stochastic_hybrid").output;
  for (const char* line : {"episode 0:", "episode 1:", "mean return"})
    EXPECT_EQ(line_starting(r.output, line), line_starting(unchecked, line)) << line;
  r = run(rollout + policy + " --controller stochastic_hybrid --plan-on simulator --plan-check 5");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(
      r.output.find("predicted return vs simulated:                     mean 1.000 median 1.000 over 4"),
      std::string::npos)
      << r.output;
  // The terminal value uses the run's trained critics, which checkpoint.pt holds: the same seed repeats
  // itself; final.pt holds none, and the terminal value is refused there rather than computed by untrained
  // critics.
  r = run(rollout + policy + " --controller stochastic_hybrid planner.terminal_value=1");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(run(rollout + policy + " --controller stochastic_hybrid planner.terminal_value=1").output,
            r.output);
  r = run(rollout + " --policy checkpoint:" + dir +
          "/final.pt --controller stochastic_hybrid planner.terminal_value=1");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("its final.pt does not"), std::string::npos) << r.output;
  // key=value overrides change the run's config before the planner is built: three samples plan otherwise.
  const std::string three =
      run(rollout + policy + " --controller stochastic_hybrid planner.samples=3").output;
  EXPECT_NE(three.find("over 2 episodes"), std::string::npos) << three;
  EXPECT_NE(three, run(rollout + policy + " --controller stochastic_hybrid").output);
  // Refused: a controller without a trained run, an unknown controller, a planner the simulator cannot
  // replace, an unknown model, overrides without a controller or of unknown keys, a plan check without a
  // stochastic planner or with a negative interval, and a controller whose networks the run has not (SAC has
  // no models).
  const std::pair<std::string, std::string> refused[] = {
      {" --policy zero --controller stochastic_hybrid", "--controller acts with a trained run's networks"},
      {policy + " --controller bogus", "unknown controller 'bogus'"},
      {policy + " --controller deterministic_hybrid --plan-on simulator", "only the stochastic planners"},
      {policy + " --controller stochastic_hybrid --plan-on dream",
       "--plan-on: 'learned', 'simulator' or 'simulator-dynamics'"},
      {policy + " planner.lambda=2", "overrides change the run's config for --controller"},
      {policy + " --plan-check 5", "--plan-check compares a stochastic planner's samples"},
      {policy + " --controller policy --plan-check 5",
       "--plan-check compares a stochastic planner's samples"},
      {policy + " --controller stochastic_hybrid --plan-check -1", "--plan-check must be >= 0"},
      {policy + " --controller stochastic_hybrid planner.lamda=2", "unknown config key 'planner.lamda'"},
  };
  for (const auto& [args, word] : refused) {
    r = run(rollout + args);
    EXPECT_EQ(r.code, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(word), std::string::npos) << args << "\n" << r.output;
  }
  const std::string sac = fresh_dir("controller_sac");
  ASSERT_EQ(run(kTrain + kSmall + " --method sac --steps 60 eval.every=0 --out " + sac).code, 0);
  r = run(rollout + " --policy checkpoint:" + sac + "/final.pt --controller stochastic_hybrid");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("needs a dynamics and reward model"), std::string::npos) << r.output;
}

TEST(ModelFitCli, FitsAModelThatBeatsNoChangeAndRefusesMismatchedRecordings) {
  const std::string dir = fresh_dir("model_fit");
  const std::string rollout = std::string(HLT_ROLLOUT_BIN) + " --env pendulum --policy random --frame-skip 4";
  ASSERT_EQ(run(rollout + " --episodes 8 --seed 1 --demos " + dir + "/train.hltd").code, 0);
  ASSERT_EQ(run(rollout + " --episodes 2 --seed 100 --demos " + dir + "/test.hltd").code, 0);
  const std::string fit = std::string(HLT_MODEL_FIT_BIN) + " --env pendulum --train " + dir +
                          "/train.hltd --test " + dir + "/test.hltd --updates 1500 --report-every 500";
  Result r = run(fit);
  ASSERT_EQ(r.code, 0) << r.output;
  // The last report: "1500 | loss | train ratio (better in k of 3) | test ratio (better in k of 3) |
  // reward ratio on train | on test". The pendulum's step is smooth: a fitted model predicts unseen
  // episodes far better than "no change".
  auto last_row = [](const std::string& output) {
    const size_t at = output.find("\n1500 | ");
    if (at == std::string::npos) return std::vector<std::string>{};
    std::vector<std::string> fields;
    std::stringstream in(output.substr(at + 1, output.find('\n', at + 1) - at - 1));
    for (std::string f; std::getline(in, f, '|');)
      fields.push_back(f);
    return fields;
  };
  std::vector<std::string> row = last_row(r.output);
  ASSERT_EQ(row.size(), 6u) << r.output;
  const double test_ratio = std::stod(row[3]);
  EXPECT_LT(test_ratio, 0.3) << row[3];
  // The default reward model has a TD target (gamma 0.95): it fits a discounted sum, so no reward score.
  EXPECT_EQ(row[5], " -");
  EXPECT_NE(r.output.find("to 400 transitions, scoring on 100"), std::string::npos) << r.output;
  // The same seed gives the same fit.
  EXPECT_EQ(run(fit).output, r.output);
  // A regressed reward model (gamma 0) is scored; the pendulum's reward is a smooth function of the state
  // and action. Open-loop predictions one step ahead are the pooled one-step score (the domain clamp off);
  // five steps ahead the fitted model still beats "no change".
  r = run(fit + " --horizons 1,5 model.reward_gamma=0 planner.clamp_to_data=false");
  ASSERT_EQ(r.code, 0) << r.output;
  row = last_row(r.output);
  ASSERT_EQ(row.size(), 6u) << r.output;
  EXPECT_LT(std::stod(row[5]), 0.3) << r.output;
  const size_t k1 = r.output.find("  k 1: "), k5 = r.output.find("  k 5: ");
  ASSERT_NE(k1, std::string::npos) << r.output;
  ASSERT_NE(k5, std::string::npos) << r.output;
  EXPECT_NEAR(std::stod(r.output.substr(k1 + 7)), std::stod(row[3]), 0.0015) << r.output;
  EXPECT_LT(std::stod(r.output.substr(k5 + 7)), 1.0) << r.output;
  // Refused (exit 2) with a message naming what is wrong: recordings of another environment, a missing file,
  // a bad override.
  const std::string tool = std::string(HLT_MODEL_FIT_BIN);
  const std::vector<std::pair<std::string, std::string>> refused = {
      {" --env acrobot --train " + dir + "/train.hltd --test " + dir + "/test.hltd", "pendulum"},
      {" --env pendulum --train " + dir + "/none.hltd --test " + dir + "/test.hltd", "none.hltd"},
      {fit.substr(tool.size()) + " model.hidden=0", "model.hidden"}};
  for (const auto& [args, word] : refused) {
    r = run(tool + args);
    EXPECT_EQ(r.code, 2) << args;
    EXPECT_NE(r.output.find(word), std::string::npos) << r.output;
  }
}

TEST(TrainCli, ResumeNeverDestroysData) {
  const std::string dir = fresh_dir("resume_guards");
  // 100 agent steps are two whole pendulum episodes: the run ends at an episode end, checkpointed.
  Result r =
      run(kTrain + kSmall + " --method sac --steps 100 checkpoint.every=50 eval.every=50 --out " + dir);
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("done: 100 agent steps (400 environment steps)"), std::string::npos) << r.output;
  const std::string log = read_file(dir + "/scalars.csv"), config = read_file(dir + "/config.yaml");
  // A smaller budget would discard trained steps.
  r = run(kTrain + " --resume " + dir + " --steps 40 --no-progress");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("has trained 100 agent steps already"), std::string::npos) << r.output;
  EXPECT_EQ(read_file(dir + "/scalars.csv"), log);
  EXPECT_EQ(read_file(dir + "/config.yaml"), config);
  // Killed while final.pt was written: resuming the finished run writes it; stale temporaries go.
  fs::remove(dir + "/final.pt");
  write_file_atomic(dir + "/final.pt.tmp.99999", "half a checkpoint");
  r = run(kTrain + " --resume " + dir + " --no-progress");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir + "/final.pt"));
  EXPECT_FALSE(fs::exists(dir + "/final.pt.tmp.99999"));
  EXPECT_EQ(read_file(dir + "/scalars.csv"), log);
  // A finished run without its checkpoint is not restarted from zero.
  fs::remove(dir + "/checkpoint.pt");
  r = run(kTrain + " --resume " + dir + " --no-progress");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("checkpoint.pt is missing but final.pt exists"), std::string::npos) << r.output;
  EXPECT_EQ(read_file(dir + "/scalars.csv"), log);
  // --out on a directory that holds only a final.pt does not overwrite it.
  const std::string only_final = fresh_dir("only_final");
  fs::create_directories(only_final);
  fs::copy_file(dir + "/final.pt", only_final + "/final.pt");
  r = run(kTrain + kSmall + " --method sac --steps 10 --out " + only_final);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("already holds a run (final.pt exists)"), std::string::npos) << r.output;
}

TEST(TrainCli, DivergedRunStopsWithAnErrorAndNoFinalWeights) {
  const std::string dir = fresh_dir("diverged");
  Result r = run(kTrain + kSmall +
                 " --method sac --steps 1500 sac.lr=1 sac.initial_alpha=10000 eval.every=0 "
                 "checkpoint.every=100 --out " +
                 dir);
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("training diverged at agent step"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir + "/final.pt"));
}

TEST(TrainCli, SecondWriterOfARunDirectoryIsRefused) {
  const std::string dir = fresh_dir("locked");
  const pid_t pid = spawn_train(kSmall + " --method sac --steps 100000 eval.every=0 --out " + dir);
  ASSERT_GT(pid, 0);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!fs::exists(dir + "/scalars.csv") && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  const std::string config = read_file(dir + "/config.yaml");
  Result r = run(kTrain + " --resume " + dir + " --no-progress");
  ::kill(pid, SIGKILL);
  ::waitpid(pid, nullptr, 0);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("is in use by process " + std::to_string(pid)), std::string::npos) << r.output;
  EXPECT_EQ(read_file(dir + "/config.yaml"), config);
}

TEST(TrainCli, FullDiskStopsTheRunWithAMessageAndKeepsWhatWasWritten) {
  const fs::path mount = fs::temp_directory_path() / "hlt_full_disk";
  fs::create_directories(mount);
  ::system(("umount " + mount.string() + " 2>/dev/null").c_str());
  if (::system(("mount -t tmpfs -o size=64k tmpfs " + mount.string() + " 2>/dev/null").c_str()) != 0)
    GTEST_SKIP() << "cannot mount a 64 KiB tmpfs here (needs root and mount permission)";
  const std::string dir = (mount / "run").string();
  Result r =
      run(kTrain + kSmall + " --method sac --steps 3000 eval.every=500 checkpoint.every=500 --out " + dir);
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("No space left on device"), std::string::npos) << r.output;
  // What was written before is intact: the config and a log that parses.
  EXPECT_NO_THROW(ScalarLogger::read(dir + "/scalars.csv"));
  EXPECT_EQ(read_file(dir + "/config.yaml").rfind("# blas: ", 0), 0u);
  for (const auto& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
  fs::remove_all(dir);
  // hlt_perceive stops at the first failed row instead of reporting frames it did not save.
  const std::string csv = (mount / "states.csv").string();
  r = run(std::string(HLT_PERCEIVE_BIN) + " --input synthetic:300 --quiet --tags " +
          std::string(HLT_SOURCE_DIR) + "/experiments/configs/perception/sawyer_tags.yaml --csv " + csv);
  EXPECT_NE(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("(disk full?)"), std::string::npos) << r.output;
  ::system(("umount " + mount.string()).c_str());
}

TEST(TrainCli, ParallelUpdatesGiveTheSameNumbers) {
  const std::string args = kSmall + " --method hybrid-stochastic --steps 200 eval.every=100";
  const std::string one = fresh_dir("threads1"), two = fresh_dir("threads2");
  Result r = run(kTrain + args + " train.threads=1 --out " + one);
  ASSERT_EQ(r.code, 0) << r.output;
  r = run(kTrain + args + " train.threads=2 --out " + two);
  ASSERT_EQ(r.code, 0) << r.output;
  const auto rows = comparable_rows(one + "/scalars.csv");
  ASSERT_GT(rows.size(), 20u);
  EXPECT_EQ(comparable_rows(two + "/scalars.csv"), rows);
  // The run records the BLAS kernel it used, first in its config.
  EXPECT_EQ(read_file(one + "/config.yaml").rfind("# blas: ", 0), 0u);
}

// A method's settings for one environment (experiments/configs/methods/<method>/<env>.yaml) apply to that
// pair only, after the environment's defaults and before the flags: the stochastic hybrid's cart-pole file
// sets a 10-step horizon, the environment's file (which NN-MPPI keeps) 5.
TEST(TrainCli, MethodSettingsForOneEnvironmentApplyToThatPairOnly) {
  const std::string args =
      " --env cartpole_swingup --seed 0 --steps 2 train.update_after=1000 eval.every=1000 eval.episodes=1 "
      "eval.components=false --no-progress";
  // The run's resolved config.yaml, read back the way --resume reads it.
  const auto resolved = [&](const std::string& method, const std::string& extra) {
    const std::string dir = fresh_dir("overlay_" + method);
    const Result r = run(kTrain + args + " --method " + method + extra + " --out " + dir);
    EXPECT_EQ(r.code, 0) << r.output;
    Config c = make_train_config();
    c.load_file(dir + "/config.yaml");
    return c;
  };
  const Config hybrid = resolved("hybrid-stochastic", "");
  EXPECT_EQ(hybrid.get_int("planner.horizon"), 10);
  EXPECT_EQ(hybrid.get_int("model.rollout_steps"), 5);
  EXPECT_EQ(hybrid.get_double("model.reward_gamma"), 0.0);
  EXPECT_EQ(hybrid.get_double("planner.terminal_value"), 0.2);
  EXPECT_EQ(hybrid.get_int("train.model_updates"), 10);
  EXPECT_EQ(hybrid.get_int("model.ensemble"), 5);
  EXPECT_EQ(hybrid.get_int("planner.samples"), 20);  // from cartpole_swingup.yaml, which the overlay leaves
  const Config mppi = resolved("mppi", "");
  EXPECT_EQ(mppi.get_int("planner.horizon"), 5);
  EXPECT_EQ(mppi.get_int("model.rollout_steps"), 1);
  EXPECT_EQ(mppi.get_int("train.model_updates"), 5);
  EXPECT_EQ(mppi.get_int("model.ensemble"), 1);
  const Config flagged = resolved("hybrid-stochastic", " planner.horizon=7");
  EXPECT_EQ(flagged.get_int("planner.horizon"), 7);
  EXPECT_EQ(flagged.get_int("model.rollout_steps"), 5);
}

// eval.trace writes each evaluation of each component step by step; the rewards of a trace add up to the
// return the log reports for it, and tracing changes none of the run's numbers.
TEST(TrainCli, EvalTraceRecordsEveryEvaluationStepByStep) {
  const std::string args = kSmall + " --method hybrid-stochastic --steps 100 eval.every=50";
  const std::string plain = fresh_dir("no_trace"), traced = fresh_dir("trace");
  Result r = run(kTrain + args + " --out " + plain);
  ASSERT_EQ(r.code, 0) << r.output;
  r = run(kTrain + args + " eval.trace=true --out " + traced);
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(comparable_rows(traced + "/scalars.csv"), comparable_rows(plain + "/scalars.csv"));
  EXPECT_FALSE(fs::exists(plain + "/eval_traces"));

  std::map<std::string, double> logged;  // "<step>/<tag>" -> value
  for (const auto& row : ScalarLogger::read(traced + "/scalars.csv"))
    logged[fmt::format("{}/{}", row.step, row.tag)] = row.value;
  int files = 0;
  for (int64_t step : {0, 200, 400}) {  // every 50 agent steps of frame skip 4
    for (const std::string component : {"", "policy", "planner"}) {
      SCOPED_TRACE(fmt::format("step {} {}", step, component));
      const std::string path =
          fmt::format("{}/eval_traces/step{}{}.csv", traced, step, component.empty() ? "" : "_" + component);
      ASSERT_TRUE(fs::exists(path));
      std::istringstream lines(read_file(path));
      std::string header, line;
      std::getline(lines, header);
      EXPECT_EQ(header.rfind("episode,step,obs_0,", 0), 0u) << header;
      EXPECT_NE(header.find(",action_0,reward,done,truncated"), std::string::npos) << header;
      int rows = 0;
      double total = 0;
      while (std::getline(lines, line)) {
        ++rows;
        // reward is the third column from the end
        std::vector<std::string> cells;
        std::istringstream split(line);
        for (std::string c; std::getline(split, c, ',');)
          cells.push_back(c);
        ASSERT_GE(cells.size(), 5u);
        EXPECT_EQ(cells[0], "0");
        EXPECT_EQ(cells[1], std::to_string(rows - 1));
        total += std::stod(cells[cells.size() - 3]);
      }
      EXPECT_EQ(rows, 50);  // one pendulum episode of 50 agent steps (eval.episodes=1)
      const std::string tag = component.empty() ? "eval/return_mean" : "eval/" + component + "_return_mean";
      ASSERT_TRUE(logged.count(fmt::format("{}/{}", step, tag)));
      EXPECT_NEAR(total, logged[fmt::format("{}/{}", step, tag)], 1e-9);
      ++files;
    }
  }
  EXPECT_EQ(files, 9);
}

TEST(TrainCli, EvalVariantsChangeNoOtherNumber) {
  const std::string args = kSmall + " --method hybrid-stochastic --steps 100 eval.every=50";
  const std::string plain = fresh_dir("no_variants"), varied = fresh_dir("variants");
  Result r = run(kTrain + args + " --out " + plain);
  ASSERT_EQ(r.code, 0) << r.output;
  r = run(kTrain + args +
          " \"eval.variants=planner.min_ess_fraction=0.5; planner.samples=2 planner.plan_samples=0\"" +
          " --out " + varied);
  ASSERT_EQ(r.code, 0) << r.output;
  std::vector<std::string> others;
  std::map<std::string, double> variant;  // "<step>/<tag>" -> value
  for (const auto& row : ScalarLogger::read(varied + "/scalars.csv")) {
    if (row.tag.rfind("eval/variant", 0) == 0)
      variant[fmt::format("{}/{}", row.step, row.tag)] = row.value;
    else if (row.tag.rfind("time/", 0) != 0)
      others.push_back(fmt::format("{},{},{:.17g}", row.step, row.tag, row.value));
  }
  EXPECT_EQ(others, comparable_rows(plain + "/scalars.csv"));
  for (int64_t step : {0, 200, 400}) {
    for (const std::string tag : {"variant0_return_mean", "variant1_return_mean", "variant1_return_std"})
      EXPECT_TRUE(variant.count(fmt::format("{}/eval/{}", step, tag))) << step << " " << tag;
  }
  EXPECT_EQ(variant.size(), 12u);
  // A variant may not change the evaluation itself, and its keys are checked like any override.
  for (const std::string bad : {"eval.episodes=3", "planner.nonsense=1", "planner.samples=0"}) {
    r = run(kTrain + args + " eval.variants=" + bad + " --out " + fresh_dir("bad_variant"));
    EXPECT_NE(r.code, 0) << bad;
    EXPECT_NE(r.output.find(bad.substr(0, bad.find('='))), std::string::npos) << r.output;
  }
}

TEST(TrainCli, KilledWhileWritingCheckpointOrFinalResumesToTheSameLog) {
  const std::string args = kSmall + " --method sac --steps 200 checkpoint.every=50 eval.every=50";
  const std::string straight = fresh_dir("write_straight");
  Result r = run(kTrain + args + " --out " + straight);
  ASSERT_EQ(r.code, 0) << r.output;
  const auto full = comparable_rows(straight + "/scalars.csv");
  for (const std::string kill : {"checkpoint.pt:2", "final.pt"}) {
    const std::string dir = fresh_dir("write_killed_" + kill.substr(0, 5));
    r = run("HLT_TEST_KILL_WRITING=" + kill + " " + kTrain + args + " --out " + dir);
    EXPECT_EQ(r.code, 128 + SIGKILL) << kill << " was not killed: " << r.output;  // as sh reports it
    EXPECT_FALSE(fs::exists(dir + "/final.pt")) << kill;
    r = run(kTrain + " --resume " + dir + " --no-progress");
    ASSERT_EQ(r.code, 0) << kill << ": " << r.output;
    EXPECT_EQ(comparable_rows(dir + "/scalars.csv"), full) << kill;
    EXPECT_TRUE(fs::exists(dir + "/final.pt")) << kill;
    for (const auto& e : fs::directory_iterator(dir))
      EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
  }
}

TEST(TrainCli, KilledRunResumesToTheSameLog) {
  const std::string args =
      kSmall + " --method hybrid-stochastic --steps 600 checkpoint.every=100 eval.every=100";
  const std::string straight = fresh_dir("straight"), killed = fresh_dir("killed");
  Result r = run(kTrain + args + " --out " + straight);
  ASSERT_EQ(r.code, 0) << r.output;

  // Start the same run, wait for its first checkpoint and a little more, then kill -9.
  const pid_t pid = spawn_train(args + " --out " + killed);
  ASSERT_GT(pid, 0);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (!fs::exists(killed + "/checkpoint.pt") && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(fs::exists(killed + "/checkpoint.pt"));
  // Kill once the log has grown past what the checkpoint holds: the run is then between checkpoints. A
  // fixed wait here was longer than the rest of the run on a fast machine.
  const auto logged_at_checkpoint = fs::file_size(killed + "/scalars.csv");
  while (fs::file_size(killed + "/scalars.csv") <= logged_at_checkpoint &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ::kill(pid, SIGKILL);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the run finished before it could be killed; make it longer";
  const auto partial = comparable_rows(killed + "/scalars.csv");
  const auto full = comparable_rows(straight + "/scalars.csv");
  ASSERT_LT(partial.size(), full.size());

  r = run(kTrain + " --resume " + killed + " --no-progress");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(comparable_rows(killed + "/scalars.csv"), full);
  // The TensorBoard event files agree too, read by an independent decoder.
  auto scalars_of = [](const std::string& dir) {
    std::string rows;
    for (const auto& e : fs::directory_iterator(dir)) {
      if (e.path().filename().string().rfind("events.out.tfevents.", 0) != 0) continue;
      const Result d = run("/usr/bin/python3 " + std::string(HLT_TFEVENTS_READER) + " " + e.path().string() +
                           " | grep -v ',time/'");
      EXPECT_EQ(d.code, 0) << d.output;
      rows += d.output;
    }
    return rows;
  };
  const std::string events = scalars_of(straight);
  EXPECT_GT(std::count(events.begin(), events.end(), '\n'), 50);
  EXPECT_EQ(scalars_of(killed), events);
}

}  // namespace
}  // namespace hlt
