// Planner and learner costs at the paper's network sizes, one thread: one planning call of each controller,
// the matrix products each planner cannot avoid (its floor), a SAC update and a model update; the stochastic
// hybrid also on an ensemble of five dynamics models.
//
// Sizes: (n=5, m=1, K=20, H=5) is the cart-pole swing-up (sin networks); (n=26, m=6, K=60, H=10) is the
// half-cheetah (ReLU networks). Dynamics hidden 200, reward 200 x 200, policy 128, critics 2 x 256.
// RobotTaskPlanner builds a robot task's acting controller exactly as hlt_train does, from the shipped
// configs: added to hlt_camera_loop's render and perceive times it gives a camera-observed step's cost.
#include <benchmark/benchmark.h>
#include <torch/torch.h>

#include <fmt/format.h>

#include "agents/learner.h"
#include "agents/model_learner.h"
#include "agents/sac.h"
#include "agents/train_config.h"
#include "envs/registry.h"
#include "hlt/control/action_sampler.h"
#include "hlt/control/deterministic_hybrid.h"
#include "hlt/control/stochastic_hybrid.h"
#include "hlt/core/runtime.h"

namespace hlt {
namespace {

struct Setup {
  int64_t n, m, K, H;
  DynamicsModel dynamics{nullptr};
  RewardModel reward{nullptr};
  GaussianPolicy policy{nullptr};
  at::Tensor state;
};

Setup make_setup(const benchmark::State& st) {
  set_torch_threads(1);
  torch::manual_seed(0);
  Setup s;
  s.n = st.range(0);
  s.m = st.range(1);
  s.K = st.range(2);
  s.H = st.range(3);
  const Activation act = s.n <= 6 ? Activation::kSin : Activation::kRelu;
  s.dynamics = DynamicsModel(DynamicsModelOptions{s.n, s.m, 200, act});
  s.reward = RewardModel(RewardModelOptions{s.n, s.m, 200});
  s.policy = GaussianPolicy(GaussianPolicyOptions{s.n, s.m, {128}, act});
  s.state = torch::randn({s.n});
  return s;
}

void planner_args(benchmark::internal::Benchmark* b) {
  b->ArgNames({"n", "m", "K", "H"});
  b->Args({5, 1, 20, 5});
  b->Args({26, 6, 60, 10});
  b->Unit(benchmark::kMicrosecond);
}

void StochasticHybridBench(benchmark::State& st) {
  Setup s = make_setup(st);
  StochasticHybrid c(std::make_shared<PolicySampler>(s.policy), s.dynamics, s.reward,
                     StochasticHybridOptions{s.H, s.K, 0.1, true, 1e-5}, s.policy);
  for (auto _ : st)
    benchmark::DoNotOptimize(c.act(s.state));
}

// The stochastic hybrid on an ensemble of five dynamics models (model.ensemble 5; their mean and their
// disagreement penalty): what the other four members' predictions add to a planning call.
void StochasticHybridEnsembleBench(benchmark::State& st) {
  Setup s = make_setup(st);
  EnsembleOptions ensemble;
  for (int i = 0; i < 4; ++i)
    ensemble.members.push_back(DynamicsModel(s.dynamics->options()));
  ensemble.disagreement_penalty = 1.0;
  const StochasticHybridOptions o{s.H, s.K, 0.1, true, 1e-5};
  StochasticHybrid c(std::make_shared<PolicySampler>(s.policy),
                     std::make_shared<LearnedRolloutModel>(s.dynamics, s.reward, false, std::move(ensemble)),
                     o, s.policy);
  for (auto _ : st)
    benchmark::DoNotOptimize(c.act(s.state));
}

void MPPIBench(benchmark::State& st) {
  Setup s = make_setup(st);
  StochasticHybrid c(std::make_shared<FilteredNoiseSampler>(0.3, 0.5), s.dynamics, s.reward,
                     StochasticHybridOptions{s.H, s.K, 0.1, true, 1e-5}, nullptr, "mppi");
  for (auto _ : st)
    benchmark::DoNotOptimize(c.act(s.state));
}

void DeterministicHybridBench(benchmark::State& st) {
  Setup s = make_setup(st);
  DeterministicHybrid c(s.policy, s.dynamics, s.reward, DeterministicHybridOptions{s.H, false, 0.999, true});
  for (auto _ : st)
    benchmark::DoNotOptimize(c.act(s.state));
}

// The matrix products of one stochastic planning call: per step, the policy's two heads (two layers each;
// skipped for NN-MPPI, which has no policy), the dynamics (two layers) and the reward (three layers), all at
// batch K, into preallocated outputs.
void stochastic_floor(benchmark::State& st, bool with_policy) {
  Setup s = make_setup(st);
  torch::InferenceMode guard;
  const auto K = s.K, n = s.n, m = s.m;
  auto x = torch::randn({K, n}), xa = torch::randn({K, n + m});
  auto h = torch::empty({K, 128}), u = torch::empty({K, m}), hd = torch::empty({K, 200}),
       d = torch::empty({K, n}), hr = torch::empty({K, 200}), r = torch::empty({K, 1});
  auto pw1 = torch::randn({n, 128}), pw2 = torch::randn({128, m}), dw1 = torch::randn({n + m, 200}),
       dw2 = torch::randn({200, n}), rw1 = torch::randn({n + m, 200}), rw2 = torch::randn({200, 200}),
       rw3 = torch::randn({200, 1});
  for (auto _ : st) {
    for (int64_t t = 0; t < s.H; ++t) {
      for (int head = 0; with_policy && head < 2; ++head) {
        at::mm_out(h, x, pw1);
        at::mm_out(u, h, pw2);
      }
      at::mm_out(hd, xa, dw1);
      at::mm_out(d, hd, dw2);
      at::mm_out(hr, xa, rw1);
      at::mm_out(hd, hr, rw2);
      at::mm_out(r, hd, rw3);
    }
    benchmark::DoNotOptimize(r.data_ptr());
  }
}

void StochasticHybridFloor(benchmark::State& st) {
  stochastic_floor(st, true);
}
void MPPIFloor(benchmark::State& st) {
  stochastic_floor(st, false);
}

// The deterministic planner's products: the batch-1 rollout (policy two heads at step 0, mean head after;
// dynamics), the Jacobian pass forward at batches H n (dynamics), H m (policy mean) and H (reward), and the
// backward products for the input gradients (one per layer).
void DeterministicHybridFloor(benchmark::State& st) {
  Setup s = make_setup(st);
  torch::InferenceMode guard;
  const auto n = s.n, m = s.m, H = s.H;
  auto w = [](int64_t a, int64_t b) { return torch::randn({a, b}); };
  auto pw1 = w(n, 128), pw2 = w(128, m), dw1 = w(n + m, 200), dw2 = w(200, n), rw1 = w(n + m, 200),
       rw2 = w(200, 200), rw3 = w(200, 1);
  auto layer = [](const at::Tensor& x, const at::Tensor& wt) { return at::mm(x, wt); };
  auto back = [](const at::Tensor& g, const at::Tensor& wt) { return at::mm(g, wt.t()); };
  auto x1 = torch::randn({1, n}), xa1 = torch::randn({1, n + m});
  auto xf = torch::randn({H * n, n + m}), xm = torch::randn({H * m, n}), xr = torch::randn({H, n + m});
  for (auto _ : st) {
    for (int64_t t = 0; t < H; ++t) {
      layer(layer(x1, pw1), pw2);
      if (t == 0) layer(layer(x1, pw1), pw2);
      layer(layer(xa1, dw1), dw2);
    }
    auto hf = layer(xf, dw1);
    auto of = layer(hf, dw2);
    back(back(of, dw2), dw1);
    auto hm = layer(xm, pw1);
    auto om = layer(hm, pw2);
    back(back(om, pw2), pw1);
    auto hr1 = layer(xr, rw1);
    auto hr2 = layer(hr1, rw2);
    auto orr = layer(hr2, rw3);
    benchmark::DoNotOptimize(back(back(back(orr, rw3), rw2), rw1).data_ptr());
    // The mode insertion gradient's two extra model evaluations at batch 2.
    auto x2 = torch::randn({2, n + m});
    layer(layer(x2, dw1), dw2);
    layer(layer(layer(x2, rw1), rw2), rw3);
  }
}

BENCHMARK(StochasticHybridBench)->Name("StochasticHybrid")->Apply(planner_args);
BENCHMARK(StochasticHybridFloor)->Name("StochasticHybridFloor")->Apply(planner_args);
BENCHMARK(StochasticHybridEnsembleBench)->Name("StochasticHybridEnsemble5")->Apply(planner_args);
BENCHMARK(MPPIBench)->Name("MPPI")->Apply(planner_args);
BENCHMARK(MPPIFloor)->Name("MPPIFloor")->Apply(planner_args);
BENCHMARK(DeterministicHybridBench)->Name("DeterministicHybrid")->Apply(planner_args);
BENCHMARK(DeterministicHybridFloor)->Name("DeterministicHybridFloor")->Apply(planner_args);

// One planning call of `method`'s acting controller on `env`, with the settings hlt_train resolves for them
// (experiments/configs/<env>.yaml and the method's overlay) and freshly initialised networks, from a reset
// state: block pushing's hybrid-stochastic (H 10, K 10 + 20 plan samples, policy 128 x 128) and block
// stacking's hybrid-imitation (H 40, K 40, policy 32 x 24).
void RobotTaskPlanner(benchmark::State& st, const std::string& env_name, const std::string& method_name) {
  set_torch_threads(1);
  torch::manual_seed(0);
  Config config = make_train_config();
  load_env_defaults(config, HLT_CONFIG_DIR, env_name);
  load_method_overlay(config, HLT_CONFIG_DIR, method_name, env_name);
  std::unique_ptr<Env> env = make_env(env_name);
  const MethodSpec& method = find_method(method_name);
  LearnedModels models;
  LearnerContext context{config, env->observation_dim(), env->action_dim(), 0, models};
  std::vector<std::unique_ptr<Learner>> learners;
  for (const LearnerUse& use : method.learners)
    learners.push_back(make_learner(use.learner, context));
  std::unique_ptr<Controller> controller = make_controller(method.controller, models, config, false);
  const Eigen::VectorXd s0 = env->reset(0);
  const at::Tensor state =
      torch::from_blob(const_cast<double*>(s0.data()), {s0.size()}, torch::kFloat64).to(torch::kFloat32);
  for (auto _ : st)
    benchmark::DoNotOptimize(controller->act(state));
  st.SetLabel(fmt::format(
      "H {} K {} (+{} plan samples)", config.get_int("planner.horizon"), config.get_int("planner.samples"),
      method.controller == "stochastic_hybrid" ? config.get_int("planner.plan_samples") : 0));
}

BENCHMARK_CAPTURE(RobotTaskPlanner, block_push, std::string("block_push"), std::string("hybrid-stochastic"))
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(RobotTaskPlanner, block_stack, std::string("block_stack"), std::string("hybrid-imitation"))
    ->Unit(benchmark::kMillisecond);

// One SAC update at batch 128 (critics 2 x 256, policy 128) and one joint model update (5 per agent step).
void SacUpdate(benchmark::State& st) {
  set_torch_threads(1);
  torch::manual_seed(0);
  const int64_t n = st.range(0), m = st.range(1);
  const Activation act = n <= 6 ? Activation::kSin : Activation::kRelu;
  Sac sac(GaussianPolicy(GaussianPolicyOptions{n, m, {128}, act}), n, m, SacOptions{});
  ReplayBuffer rb(1000, n, m, 0);
  std::vector<double> s(n, 0.1), a(m, 0.2);
  for (int i = 0; i < 1000; ++i)
    rb.add(s.data(), a.data(), 1.0, s.data(), a.data(), false);
  for (auto _ : st)
    benchmark::DoNotOptimize(sac.update(rb.sample(128)));
}

void ModelUpdate(benchmark::State& st) {
  set_torch_threads(1);
  torch::manual_seed(0);
  const int64_t n = st.range(0), m = st.range(1);
  const Activation act = n <= 6 ? Activation::kSin : Activation::kRelu;
  ModelLearner learner(DynamicsModel(DynamicsModelOptions{n, m, 200, act}),
                       RewardModel(RewardModelOptions{n, m, 200}), ModelLearnerOptions{});
  ReplayBuffer rb(1000, n, m, 0);
  std::vector<double> s(n, 0.1), a(m, 0.2);
  for (int i = 0; i < 1000; ++i)
    rb.add(s.data(), a.data(), 1.0, s.data(), a.data(), false);
  for (auto _ : st)
    benchmark::DoNotOptimize(learner.update(rb.sample(128)));
}

// One model update on 128 sequences of K transitions (model.rollout_steps K): the dynamics model's open-loop
// loss by autograd through K steps, the reward model on the 128 first transitions. Its unavoidable work is
// about K times the dynamics part of ModelUpdate's.
void ModelUpdateSequences(benchmark::State& st) {
  set_torch_threads(1);
  torch::manual_seed(0);
  const int64_t n = st.range(0), m = st.range(1);
  const Activation act = n <= 6 ? Activation::kSin : Activation::kRelu;
  ModelLearnerOptions options;
  options.rollout_steps = st.range(2);
  ModelLearner learner(DynamicsModel(DynamicsModelOptions{n, m, 200, act}),
                       RewardModel(RewardModelOptions{n, m, 200}), options);
  ReplayBuffer rb(1000, n, m, 0);
  std::vector<double> s(n, 0.1), a(m, 0.2);
  for (int i = 0; i < 1000; ++i)  // one episode: every next state is the following state
    rb.add(s.data(), a.data(), 1.0, s.data(), a.data(), false);
  for (auto _ : st)
    benchmark::DoNotOptimize(learner.update(rb.sample(128, options.rollout_steps)));
}

BENCHMARK(SacUpdate)->ArgNames({"n", "m"})->Args({5, 1})->Args({26, 6})->Unit(benchmark::kMillisecond);
BENCHMARK(ModelUpdate)->ArgNames({"n", "m"})->Args({5, 1})->Args({26, 6})->Unit(benchmark::kMillisecond);
BENCHMARK(ModelUpdateSequences)
    ->ArgNames({"n", "m", "K"})
    ->Args({26, 6, 1})
    ->Args({26, 6, 5})
    ->Args({26, 6, 20})
    ->Unit(benchmark::kMillisecond);

// The matrix products of one agent step at batch 128 (the paper's sizes; critics 2 x 256, policy 128, models
// 200 and 200 x 200): the stochastic planner's call (as StochasticHybridFloor, K = 20, H = 5), one SAC update
// and five model updates. Each layer's forward is one product; each backward product a learner cannot avoid
// is one more (weight gradients of the trained layers, input gradients where they flow on).
struct MlpShapes {
  std::vector<at::Tensor> w, h, dw, dh;  // weights [in, out], activations, weight and input gradients
  MlpShapes(int64_t batch, std::vector<int64_t> widths) {
    for (size_t i = 0; i + 1 < widths.size(); ++i) {
      w.push_back(torch::randn({widths[i], widths[i + 1]}));
      dw.push_back(torch::empty({widths[i], widths[i + 1]}));
      h.push_back(torch::empty({batch, widths[i + 1]}));
      dh.push_back(torch::empty({batch, widths[i]}));
    }
  }
  void forward(const at::Tensor& x) {
    for (size_t i = 0; i < w.size(); ++i)
      at::mm_out(h[i], i == 0 ? x : h[i - 1], w[i]);
  }
  // Backward from the output's gradient `g` (the shape of the last activation).
  void backward(const at::Tensor& x, bool weight_grads, bool input_grad) {
    for (size_t i = w.size(); i-- > 0;) {
      const at::Tensor& g = i + 1 == w.size() ? h.back() : dh[i + 1];
      if (weight_grads) at::mm_out(dw[i], (i == 0 ? x : h[i - 1]).t(), g);
      if (i > 0 || input_grad) at::mm_out(dh[i], g, w[i].t());
    }
  }
};

void agent_step_floor(benchmark::State& st, bool plan, bool sac, int model_steps) {
  set_torch_threads(1);
  torch::manual_seed(0);
  torch::InferenceMode guard;
  const int64_t n = st.range(0), m = st.range(1), B = 128;
  const at::Tensor s = torch::randn({B, n}), sa = torch::randn({B, n + m});
  MlpShapes critic(B, {n + m, 256, 256, 1}), policy(B, {n, 128, m}), dynamics(B, {n + m, 200, n}),
      reward(B, {n + m, 200, 200, 1});
  // The planning call's products (the same as StochasticHybridFloor at K = 20, H = 5).
  const int64_t K = 20, H = 5;
  MlpShapes p_policy(K, {n, 128, m}), p_dynamics(K, {n + m, 200, n}), p_reward(K, {n + m, 200, 200, 1});
  const at::Tensor xk = torch::randn({K, n}), xak = torch::randn({K, n + m});
  for (auto _ : st) {
    for (int64_t t = 0; plan && t < H; ++t) {
      p_policy.forward(xk);
      p_policy.forward(xk);
      p_dynamics.forward(xak);
      p_reward.forward(xak);
    }
    // SAC: the target (policy at s' with both heads, two target critics), the critics' step (two forwards,
    // two backwards with weight gradients), the policy's step (both heads, two critics forward and backward
    // to the action, the heads' backward with weight gradients).
    for (int head = 0; sac && head < 2; ++head)
      policy.forward(s);
    for (int q = 0; sac && q < 2; ++q)
      critic.forward(sa);
    for (int q = 0; sac && q < 2; ++q) {
      critic.forward(sa);
      critic.backward(sa, true, false);
    }
    for (int head = 0; sac && head < 2; ++head)
      policy.forward(s);
    for (int q = 0; sac && q < 2; ++q) {
      critic.forward(sa);
      critic.backward(sa, false, true);
    }
    for (int head = 0; sac && head < 2; ++head)
      policy.backward(s, true, false);
    // Five model steps: dynamics forward and backward, reward at (s, a) forward and backward and at (s', a')
    // forward for its TD target.
    for (int k = 0; k < model_steps; ++k) {
      dynamics.forward(sa);
      dynamics.backward(sa, true, false);
      reward.forward(sa);
      reward.forward(sa);
      reward.backward(sa, true, false);
    }
    benchmark::DoNotOptimize(reward.dw[0].data_ptr());
  }
}
void AgentStepFloor(benchmark::State& st) {
  agent_step_floor(st, true, true, 5);
}
// Its parts: one SAC update's products, one model update's.
void SacUpdateFloor(benchmark::State& st) {
  agent_step_floor(st, false, true, 0);
}
void ModelUpdateFloor(benchmark::State& st) {
  agent_step_floor(st, false, false, 1);
}
BENCHMARK(SacUpdateFloor)->ArgNames({"n", "m"})->Args({5, 1})->Args({26, 6})->Unit(benchmark::kMillisecond);
BENCHMARK(ModelUpdateFloor)->ArgNames({"n", "m"})->Args({5, 1})->Args({26, 6})->Unit(benchmark::kMillisecond);
BENCHMARK(AgentStepFloor)->ArgNames({"n", "m"})->Args({5, 1})->Args({26, 6})->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace hlt
