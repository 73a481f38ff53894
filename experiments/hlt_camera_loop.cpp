// hlt_camera_loop: runs a camera-observed robot task (block_push_camera, block_stack_camera) with a policy
// that needs no trained model and reports, over whole episodes, the state estimator's error against the
// simulator (per object: mean, 95th percentile, maximum, misses) and the time per control step (render,
// perceive, rest; median and 95th percentile). The same report as hlt_rollout --perception, without
// LibTorch (so without checkpoint policies), which keeps the tool light to build and to start.
//
//   hlt_camera_loop --env block_stack_camera --policy scripted:block_stack_camera --episodes 5 --seed 0
//                   [--max-steps T] [--image FILE.png]
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <opencv2/imgcodecs.hpp>

#include "envs/registry.h"
#include "envs/rollout.h"
#include "experiments/cli_checks.h"
#include "experiments/perception_report.h"
#include "hlt/util/error.h"
#include "hlt/util/main_guard.h"
#include "hlt/util/random.h"

namespace hlt {
namespace {

struct Options {
  std::string env = "block_push_camera";
  std::string policy = "random";
  int episodes = 1;
  uint64_t seed = 0;
  int max_steps = 0;
  std::string image;  // the camera's first frame of the first episode
};

int run(const Options& o) {
  std::unique_ptr<Env> env = make_env(o.env);
  const robot::CameraObserved* camera = camera_task(*env);
  check(camera != nullptr,
        "--env {}: not a camera-observed environment (block_push_camera, block_stack_camera)", o.env);
  check(o.episodes >= 1, "--episodes must be at least 1, got {}", o.episodes);
  check(o.max_steps >= 0, "--max-steps must be >= 0, got {}", o.max_steps);
  check(o.image.empty() || (o.image.size() > 4 && o.image.substr(o.image.size() - 4) == ".png"),
        "--image {}: use a .png file name", o.image);
  // The same policy stream as hlt_rollout's, so both tools run the same episodes.
  std::unique_ptr<PolicySource> policy = make_policy_for(o.policy, *env, derive_seed(o.seed, 1));
  fmt::print("env {}, policy {}, seed {}\n", o.env, policy->describe(), o.seed);
  PerceptionReport report(*camera);
  for (int ep = 0; ep < o.episodes; ++ep) {
    auto on_reset = [&] {
      if (ep == 0 && !o.image.empty())
        check(cv::imwrite(o.image, camera->last_image()), "cannot write {}", o.image);
      report.after_reset();
    };
    auto on_step = [&](const Transition&) { report.after_step(); };
    const EpisodeStats s =
        run_episode(*env, *policy, ep == 0 ? std::optional<uint64_t>(o.seed) : std::nullopt, on_step,
                    on_reset, o.max_steps);
    fmt::print("episode {}: return {:.2f} length {}{}\n", ep, s.episode_return, s.length,
               s.success ? (*s.success ? " success" : " no success") : "");
    std::fflush(stdout);  // a line per episode as it ends, also into a pipe
  }
  report.print();
  return 0;
}

}  // namespace
}  // namespace hlt

int run_tool(int argc, char** argv) {
  hlt::Options o;
  CLI::App app{"Runs a camera-observed robot task and reports the estimator's error and the step timings."};
  app.add_option("--env", o.env, "block_push_camera or block_stack_camera")->capture_default_str();
  app.add_option("--policy", o.policy, "zero | random | constant:V[,V2,...] | scripted:NAME")
      ->capture_default_str();
  app.add_option("--episodes", o.episodes, "Number of episodes")->capture_default_str();
  app.add_option("--seed", o.seed, "Seed of the first reset (and of the random policy)")
      ->capture_default_str();
  app.add_option("--max-steps", o.max_steps, "Cut each episode after this many steps (0: the env's limit)")
      ->capture_default_str();
  app.add_option("--image", o.image, "Write the camera's first image (PNG)");
  if (const std::optional<int> code = hlt::parse_command_line(app, argc, argv)) return *code;
  hlt::check_finite_flags(app);
  return hlt::run(o);
}

int main(int argc, char** argv) {
  return hlt::guarded_main("hlt_camera_loop", [&] { return run_tool(argc, argv); });
}
