// Environment costs: one step (random actions, and smooth ones; episodes reset outside the timing), a
// snapshot save+restore pair (what a planner pays per branch) and one rendered frame, for every registered
// environment.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "envs/env.h"
#include "envs/registry.h"

namespace hlt {
namespace {

std::vector<Eigen::VectorXd> random_actions(int dim, int count) {
  std::mt19937_64 rng(0);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::VectorXd> out(count, Eigen::VectorXd(dim));
  for (auto& a : out)
    for (int i = 0; i < dim; ++i)
      a[i] = u(rng);
  return out;
}

void env_step(benchmark::State& state, const std::string& name, int frame_skip) {
  std::unique_ptr<Env> env = make_env(name);
  if (frame_skip > 1) env = std::make_unique<FrameSkip>(std::move(env), frame_skip);
  const auto actions = random_actions(env->action_dim(), 4096);
  env->reset(0);
  size_t i = 0;
  for (auto _ : state) {
    const StepResult r = env->step(actions[i++ % actions.size()]);
    benchmark::DoNotOptimize(r.reward);
    if (r.done()) {
      state.PauseTiming();
      env->reset();
      state.ResumeTiming();
    }
  }
  state.SetItemsProcessed(state.iterations());
}

// The same with smooth actions a_i = sin(0.3 t + i): the locomotion robots stay on their feet (or on the
// ground) longer than under random actions, so more of the steps carry contacts.
void env_step_smooth(benchmark::State& state, const std::string& name) {
  std::unique_ptr<Env> env = make_env(name);
  env->reset(0);
  Eigen::VectorXd a(env->action_dim());
  long t = 0;
  for (auto _ : state) {
    for (int i = 0; i < a.size(); ++i)
      a[i] = std::sin(0.3 * t + i);
    ++t;
    const StepResult r = env->step(a);
    benchmark::DoNotOptimize(r.reward);
    if (r.done()) {
      state.PauseTiming();
      env->reset();
      t = 0;
      state.ResumeTiming();
    }
  }
  state.SetItemsProcessed(state.iterations());
}

void env_save_restore(benchmark::State& state, const std::string& name) {
  std::unique_ptr<Env> env = make_env(name);
  env->reset(0);
  env->step(Eigen::VectorXd::Constant(env->action_dim(), 0.3));
  for (auto _ : state) {
    const EnvState s = env->save_state();
    env->restore_state(s);
    benchmark::DoNotOptimize(s.sim.data());
  }
}

void env_render(benchmark::State& state, const std::string& name) {
  std::unique_ptr<Env> env = make_env(name);
  env->reset(0);
  env->step(Eigen::VectorXd::Constant(env->action_dim(), 0.3));
  for (auto _ : state) {
    cv::Mat img = env->render(480, 360);
    benchmark::DoNotOptimize(img.data);
  }
}

const bool registered = [] {
  for (const std::string& name : env_names()) {
    benchmark::RegisterBenchmark(("BM_EnvStep/" + name).c_str(), env_step, name, 1);
    benchmark::RegisterBenchmark(("BM_EnvStepSmooth/" + name).c_str(), env_step_smooth, name);
    benchmark::RegisterBenchmark(("BM_EnvSaveRestore/" + name).c_str(), env_save_restore, name);
    benchmark::RegisterBenchmark(("BM_EnvRender/" + name).c_str(), env_render, name);
  }
  // A frame-skipped step costs k simulator steps plus the wrapper.
  benchmark::RegisterBenchmark("BM_EnvStep/cartpole_swingup_frameskip4", env_step,
                               std::string("cartpole_swingup"), 4);
  return true;
}();

}  // namespace
}  // namespace hlt
