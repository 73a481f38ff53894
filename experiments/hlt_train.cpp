// hlt_train: trains any method on any registered environment.
//
//   hlt_train --env cartpole_swingup --method hybrid-stochastic --seed 0 --steps 10000 --out runs/x
//             [--config FILE] [key=value ...]
//   hlt_train --env ant --method hybrid-imitation --seed 0 --steps 10 --out runs/y   (10 demonstrations)
//   hlt_train --resume runs/x [--steps N]
//
// Settings are resolved in order: declared defaults, experiments/configs/<env>.yaml, the method's overlay
// experiments/configs/methods/<method>.yaml and its settings for this environment
// experiments/configs/methods/<method>/<env>.yaml (each if there is one), --config FILE, the flags above,
// then key=value overrides. `hlt_train --list` prints every key.
#include <cmath>
#include <filesystem>
#include <iostream>
#include <optional>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>
#include <CLI/CLI.hpp>

#include <fmt/ranges.h>
#include "agents/methods.h"
#include "agents/train_config.h"
#include "agents/trainer.h"
#include "envs/registry.h"
#include "experiments/cli_checks.h"
#include "hlt/simd/vector_math.h"
#include "hlt/util/blas_kernel.h"
#include "hlt/util/error.h"
#include "hlt/util/files.h"
#include "hlt/util/main_guard.h"
#include "hlt/util/progress_bar.h"
#include "hlt/util/scalar_logger.h"

namespace fs = std::filesystem;

namespace hlt {
namespace {

// The env (or method) a config file names, if any (needed before the env's and the method's default files
// can be loaded).
std::optional<std::string> key_in_file(const std::string& path, const char* key) {
  try {
    YAML::Node root = YAML::Load(read_file(path));
    if (root.IsMap() && root[key]) return root[key].as<std::string>();
  } catch (const YAML::Exception& e) {
    throw Error(fmt::format("malformed YAML in {}: {}", path, e.what()));
  }
  return std::nullopt;
}

// The shipped configs name expert files relative to the repository (agents/experts/...): found from any
// working directory, recorded in the run's config as the absolute path that was used.
void resolve_expert_path(Config& config) {
  const std::string spec = config.get_string("imitation.expert");
  const std::string prefix = "expert:";
  if (spec.rfind(prefix, 0) != 0) return;
  const fs::path file = spec.substr(prefix.size());
  const fs::path in_repository = fs::path(HLT_CONFIG_DIR).parent_path().parent_path() / file;
  if (file.is_relative() && !fs::exists(file) && fs::exists(in_repository))
    config.set("imitation.expert", prefix + in_repository.lexically_normal().string(), "repository path");
}

void print_summary(const Trainer& trainer) {
  const Trainer::Summary s = trainer.summary();
  // The returns are NaN when none happened in this session (eval.every=0, a run shorter than an episode):
  // said in words, since "return nan" reads like a diverged run.
  auto value = [](double x, const char* none) {
    return std::isnan(x) ? std::string(none) : fmt::format("{:.1f}", x);
  };
  if (s.iterations >= 0) {
    // An imitation run counts iterations; its agent steps are the test episodes'.
    fmt::print(
        "done: {} iterations ({} demonstrations; {} agent steps, {} environment steps); last test "
        "return {}\n",
        s.iterations, s.iterations, s.agent_steps, s.env_steps,
        value(s.last_eval, "none (no iteration in this session)"));
  } else {
    fmt::print(
        "done: {} agent steps ({} environment steps); last evaluation return {}, last training episode "
        "return {}\n",
        s.agent_steps, s.env_steps, value(s.last_eval, "none (no evaluation in this session)"),
        value(s.last_return, "none (no episode ended in this session)"));
  }
  fmt::print("results in {}/ ({}, {}, {}, {})\n", trainer.run_dir(), Trainer::kLogFile, Trainer::kConfigFile,
             Trainer::kFinalFile, Trainer::kCheckpointFile);
}

int run(int argc, char** argv) {
  CLI::App app{"Train a hybrid-learning method (or a baseline) on an environment."};
  std::string env, method, out, config_file, resume;
  std::optional<int64_t> seed, steps;
  std::vector<std::string> overrides;
  bool list = false, no_progress = false;
  app.add_option(
      "--env", env,
      fmt::format("{} (default {})", fmt::join(env_names(), " | "), make_train_config().get_string("env")));
  app.add_option("--method", method, fmt::format("{}", fmt::join(method_names(), " | ")));
  app.add_option("--seed", seed, "run seed");
  app.add_option("--steps", steps,
                 "agent steps to train for, or iterations for an imitation method (with --resume: the new "
                 "total)");
  app.add_option("--out", out, "run directory (default runs/<env>/<method>/seed<seed>)");
  app.add_option("--config", config_file, "YAML config file applied after the environment's defaults");
  app.add_option("--resume", resume, "continue the run in this directory from its last checkpoint");
  app.add_flag("--list", list, "print every config key with its default and allowed values, then exit");
  app.add_flag("--no-progress", no_progress,
               "no progress bar (it is also off when stderr is not a terminal)");
  app.add_option("overrides", overrides, "key=value config overrides, e.g. planner.samples=60");
  if (const std::optional<int> code = hlt::parse_command_line(app, argc, argv)) return *code;
  check_finite_flags(app);

  if (list) {
    fmt::print("config keys (set in a YAML file or as key=value):\n{}", make_train_config().describe());
    return 0;
  }
  const bool progress = !no_progress && ProgressBar::stderr_is_terminal();
  if (!resume.empty()) {
    check(env.empty() && method.empty() && !seed && config_file.empty() && overrides.empty() && out.empty(),
          "--resume continues a run with its own config; only --steps may be given with it");
    auto trainer = Trainer::resume(resume, steps);
    fmt::print("resuming {} ({} on {})\n", resume, trainer->config().get_string("method"),
               trainer->config().get_string("env"));
    trainer->run(progress);
    print_summary(*trainer);
    return 0;
  }

  Config config = make_train_config();
  std::string env_name = env;
  if (env_name.empty() && !config_file.empty()) env_name = key_in_file(config_file, "env").value_or("");
  if (env_name.empty()) env_name = config.get_string("env");
  config.set("env", env_name, "--env");  // validates the name before its file is looked up
  load_env_defaults(config, HLT_CONFIG_DIR, env_name);
  std::string method_name = method;
  if (method_name.empty() && !config_file.empty())
    method_name = key_in_file(config_file, "method").value_or("");
  if (method_name.empty()) method_name = config.get_string("method");
  config.set("method", method_name, "--method");  // validates the name before its overlay is looked up
  load_method_overlay(config, HLT_CONFIG_DIR, method_name, env_name);
  if (!config_file.empty()) config.load_file(config_file);
  // The flags come after the file (the documented order), --env included.
  if (!env.empty()) config.set("env", env, "--env");
  if (!method.empty()) config.set("method", method, "--method");
  if (seed) config.set("seed", std::to_string(*seed), "--seed");
  if (steps) config.set(Trainer::budget_key(config), std::to_string(*steps), "--steps");
  for (const auto& o : overrides)
    config.apply_override(o);
  resolve_expert_path(config);
  if (out.empty()) {
    out = fmt::format("runs/{}/{}/seed{}", config.get_string("env"), config.get_string("method"),
                      config.get_int("seed"));
  }
  auto trainer = Trainer::create(config, out);
  const bool imitation = find_method(config.get_string("method")).loop == kImitationLoop;
  fmt::print("training {} on {} (seed {}, {}, frame skip {}) into {}\n", config.get_string("method"),
             config.get_string("env"), config.get_int("seed"),
             imitation ? fmt::format("{} iterations", config.get_int("imitation.iterations"))
                       : fmt::format("{} agent steps", config.get_int("train.agent_steps")),
             config.get_int("train.frame_skip"), out);
  fmt::print("blas: {}\nvector kernels: {}\n", blas_kernel().summary(), vector_isa());
  trainer->run(progress);
  print_summary(*trainer);
  return 0;
}

}  // namespace
}  // namespace hlt

int main(int argc, char** argv) {
  return hlt::guarded_main("hlt_train", [&] { return hlt::run(argc, argv); });
}
