#include "agents/trainer.h"

#include <ATen/CPUGeneratorImpl.h>
#include <torch/torch.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>

#include "agents/controller_policy.h"
#include "agents/learner.h"
#include "agents/methods.h"
#include "agents/model_check.h"
#include "agents/policy_spec.h"
#include "agents/train_config.h"
#include "envs/registry.h"
#include "hlt/core/checkpoint.h"
#include "hlt/core/runtime.h"
#include "hlt/data/replay_buffer.h"
#include "hlt/simd/vector_math.h"
#include "hlt/util/blas_kernel.h"
#include "hlt/util/directory_lock.h"
#include "hlt/util/error.h"
#include "hlt/util/files.h"
#include "hlt/util/progress_bar.h"
#include "hlt/util/random.h"
#include "hlt/util/scalar_logger.h"
#include "hlt/util/worker_thread.h"

namespace hlt {
namespace fs = std::filesystem;
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// The non-empty pieces of `text` between `separator`s.
std::vector<std::string> split(const std::string& text, char separator) {
  std::vector<std::string> pieces;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t end = std::min(text.find(separator, start), text.size());
    if (end > start) pieces.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  return pieces;
}

// Seed streams derived from the run seed (see derive_seed). Learner i's generator is kLearnerNoise + i (SAC,
// first wherever it trains, keeps the stream it always had).
enum Stream : uint64_t {
  kReplay = 1,
  kTrainEpisode = 2,
  kEvalEpisode = 3,
  kLearnerNoise = 4,
  kDemonstrationReplay = 64,
  kDemonstrationEpisode = 65,
  kDemonstrator = 66,
  kImitationEval = 67,
  kDemonstratorNoise = 68,
};

// The header of config.yaml: what the run's numbers depend on besides its settings. The same seed gives
// the same numbers only with the same BLAS kernel and the same vector instruction set (sin and cos differ
// between SLEEF's builds in their last bits).
std::string run_notes() {
  return "blas: " + blas_kernel().summary() + "; vector: " + vector_isa();
}

struct Stats {
  double sum = 0;
  int64_t count = 0;
  void add(double x) {
    sum += x;
    ++count;
  }
  double mean() const { return count ? sum / count : std::nan(""); }
};

}  // namespace

struct Trainer::Impl {
  Config config;
  std::string dir;
  std::unique_ptr<DirectoryLock> lock;  // held for as long as this process may write the run
  const MethodSpec* method = nullptr;
  uint64_t seed = 0;
  std::unique_ptr<FrameSkip> env, eval_env;
  LearnedModels models;
  // A learner of the method with the data it samples and this episode's (or iteration's) mean losses.
  struct ActiveLearner {
    std::unique_ptr<Learner> learner;
    ReplayBuffer* data = nullptr;
    int64_t updates = 0;  // per agent step (online loop) or per iteration (imitation loop)
    std::vector<std::pair<const char*, Stats>> losses;
  };
  std::vector<ActiveLearner> learners;
  std::unique_ptr<ReplayBuffer> buffer;          // D
  std::unique_ptr<ReplayBuffer> demonstrations;  // D_exp (imitation loop only)
  bool imitation = false;
  std::unique_ptr<Controller> controller;
  std::vector<std::pair<std::string, std::unique_ptr<Controller>>> evaluators;  // label, controller
  // eval.variants: evaluated after the others with the generator's state put back, so the run is unchanged.
  std::vector<std::pair<std::string, std::unique_ptr<Controller>>> variant_evaluators;
  std::unique_ptr<ScalarLogger> log;
  // train.threads = 2: runs the first learner's updates (SAC's) beside the others'.
  std::unique_ptr<WorkerThread> worker;

  // Per-step settings, read from the config once.
  int64_t update_after = 0, batch_size = 0, eval_every = 0;

  // Counters (checkpointed). The imitation loop counts iterations (= demonstrations); its agent steps are
  // those of its test episodes (what the deterministic hybrid's exploration decays with).
  int64_t agent_steps = 0, env_steps = 0, episodes = 0, evaluations = 0, iterations = 0;
  double wall_before = 0;  // seconds spent in earlier sessions of this run
  Clock::time_point session_start = Clock::now();
  int64_t next_checkpoint = 0;

  // The current episode.
  bool need_reset = true;
  Eigen::VectorXd obs;
  struct Pending {
    Eigen::VectorXd s, a, s2;
    double r = 0;
    bool valid = false;
  } pending;
  double ep_return = 0;
  int64_t ep_env_steps = 0, ep_agent_steps = 0, ep_fallbacks_start = 0;
  Stats ep_mig, ep_ess, ep_saturated;
  double ep_act_seconds = 0, ep_update_seconds = 0, ep_eval_seconds = 0;
  Clock::time_point ep_start;
  double last_return = std::nan(""), last_eval = std::nan("");

  double wall_time() const { return wall_before + seconds_since(session_start); }

  void build() {
    seed = static_cast<uint64_t>(config.get_int("seed"));
    set_torch_threads(static_cast<int>(config.get_int("threads")));
    seed_torch(seed);
    method = &find_method(config.get_string("method"));
    const std::string env_name = config.get_string("env");
    const int k = static_cast<int>(config.get_int("train.frame_skip"));
    env = std::make_unique<FrameSkip>(make_env(env_name), k);
    eval_env = std::make_unique<FrameSkip>(make_env(env_name), k);
    const int64_t n = env->observation_dim(), m = env->action_dim();

    imitation = method->loop == kImitationLoop;
    // Each learner adds the networks it trains to `models`, in the method's order (which fixes the order
    // in which they draw their initial weights).
    for (size_t i = 0; i < method->learners.size(); ++i) {
      LearnerContext context{
          config, n, m, derive_seed(seed, kLearnerNoise + i), models, env->observation_scale()};
      learners.push_back({make_learner(method->learners[i].learner, context),
                          nullptr,
                          config.get_int(method->learners[i].updates_key),
                          {}});
    }
    buffer = std::make_unique<ReplayBuffer>(config.get_int("train.replay_capacity"), n, m,
                                            derive_seed(seed, kReplay));
    if (imitation) {
      // As large as D (not sized by the iterations, so that a resumed run may be given more of them).
      demonstrations = std::make_unique<ReplayBuffer>(config.get_int("train.replay_capacity"), n, m,
                                                      derive_seed(seed, kDemonstrationReplay));
      // A missing or mismatched demonstrator stops the run before it writes anything.
      const std::string expert = config.get_string("imitation.expert");
      check(!expert.empty(), "method {} needs a demonstrator: set imitation.expert (e.g. expert:PATH)",
            method->name);
      make_fixed_policy(expert, *env, 0, "imitation.expert");
    }
    for (size_t i = 0; i < learners.size(); ++i) {
      const std::string& data = method->learners[i].data;
      check(data == kReplayData || (data == kDemonstrationData && demonstrations),
            "method {}: learner {} trains on '{}', which its loop does not collect", method->name,
            method->learners[i].learner, data);
      learners[i].data = data == kReplayData ? buffer.get() : demonstrations.get();
    }
    // The imitation loop's test episodes act with the policy's mean when the method has no planner (bc).
    controller = make_controller(method->controller, models, config,
                                 /*evaluation=*/imitation && method->controller == "policy");
    evaluators.emplace_back("", make_controller(method->controller, models, config, /*evaluation=*/true));
    if (config.get_bool("eval.components") && !method->planner_controller.empty() && models.policy &&
        models.dynamics) {
      evaluators.emplace_back("policy", make_controller("policy", models, config, true));
      evaluators.emplace_back("planner", make_controller(method->planner_controller, models, config, true));
    }
    if (config.get_bool("eval.compare_density") && method->controller == "stochastic_hybrid") {
      // Diagnostic: the same networks planned with the other p(v) (squashed vs Gaussian density).
      Config other = config;
      other.set("planner.density_tanh_correction",
                config.get_bool("planner.density_tanh_correction") ? "false" : "true",
                "eval.compare_density");
      evaluators.emplace_back("other_density", make_controller(method->controller, models, other, true));
    }
    const std::vector<std::string> variants = split(config.get_string("eval.variants"), ';');
    for (size_t v = 0; v < variants.size(); ++v) {
      Config other = config;
      for (const std::string& kv : split(variants[v], ' ')) {
        check(kv.rfind("eval.", 0) != 0,
              "eval.variants: '{}' sets an evaluation key; a variant may only "
              "change how the controller is built",
              kv);
        other.apply_override(kv);
      }
      variant_evaluators.emplace_back(fmt::format("variant{}", v),
                                      make_controller(method->controller, models, other, true));
    }
    next_checkpoint = config.get_int("checkpoint.every");
    update_after = config.get_int("train.update_after");
    batch_size = config.get_int("train.batch_size");
    eval_every = config.get_int("eval.every");
    if (config.get_int("train.threads") > 1 && learners.size() > 1) worker = std::make_unique<WorkerThread>();
  }

  // Exploration decays with agent steps (calls to the environment's step), as in the authors' code.
  void tell_interactions(Controller& c) const { c.set_interactions(agent_steps); }

  at::Tensor act(Controller& c, const Eigen::VectorXd& state) {
    tell_interactions(c);
    return c.act(observation_tensor(state));
  }

  void begin_episode() {
    obs = env->reset(derive_seed(seed, kTrainEpisode) ^ static_cast<uint64_t>(episodes));
    controller->reset();
    need_reset = false;
    ep_return = 0;
    ep_env_steps = ep_agent_steps = 0;
    ep_fallbacks_start = controller->diagnostics().fallbacks;
    ep_mig = ep_ess = ep_saturated = Stats{};
    clear_losses();
    ep_act_seconds = ep_update_seconds = ep_eval_seconds = 0;
    ep_start = Clock::now();
  }

  void step() {
    if (need_reset) begin_episode();
    auto t0 = Clock::now();
    const Eigen::VectorXd a = action_vector(act(*controller, obs));
    ep_act_seconds += seconds_since(t0);
    const double mig = controller->diagnostics().mode_insertion_gradient;
    if (std::isfinite(mig)) ep_mig.add(mig);
    const double ess = controller->diagnostics().weight_ess;
    if (std::isfinite(ess)) ep_ess.add(ess);
    const double saturated = controller->diagnostics().saturated_weight;
    if (std::isfinite(saturated)) ep_saturated.add(saturated);
    if (pending.valid) {
      // The previous transition's next action a' is the one just chosen.
      buffer->add(pending.s.data(), pending.a.data(), pending.r, pending.s2.data(), a.data(), false);
      pending.valid = false;
    }
    const StepResult res = env->step(a);
    if (!res.failure.empty()) fmt::print(stderr, "warning: {}\n", res.failure);
    ++agent_steps;
    ++ep_agent_steps;
    env_steps += env->last_step_frames();
    ep_env_steps += env->last_step_frames();
    ep_return += res.reward;
    if (res.terminated) {
      buffer->add(obs.data(), a.data(), res.reward, res.observation.data(), a.data(), true);
    } else if (res.truncated) {
      // Cut by the time limit: s' is not terminal, so its next action is the controller's choice there.
      t0 = Clock::now();
      const Eigen::VectorXd a2 = action_vector(act(*controller, res.observation));
      ep_act_seconds += seconds_since(t0);
      buffer->add(obs.data(), a.data(), res.reward, res.observation.data(), a2.data(), false);
    } else {
      pending = {obs, a, res.observation, res.reward, true};
    }
    obs = res.observation;

    t0 = Clock::now();
    update();
    ep_update_seconds += seconds_since(t0);

    if (eval_every > 0 && agent_steps % eval_every == 0) {
      t0 = Clock::now();
      evaluate();
      ep_eval_seconds += seconds_since(t0);
    }
    if (res.done()) end_episode();
  }

  // An agent step's learner updates (online loop).
  void update() {
    if (buffer->size() < update_after) return;
    train_learners();
  }

  // Every learner's updates. Every batch is drawn first (in the learners' order), and a learner's own
  // randomness comes from its own generator; learners share no trained parameters, so running the first
  // one concurrently with the others (train.threads = 2) computes exactly what running them one after the
  // other does.
  void train_learners() {
    std::vector<std::vector<Batch>> batches(learners.size());
    for (size_t i = 0; i < learners.size(); ++i)
      for (int64_t u = 0; u < learners[i].updates; ++u)
        batches[i].push_back(learners[i].data->sample(batch_size * learners[i].learner->batch_multiple(),
                                                      learners[i].learner->sequence_steps()));
    auto train = [&](size_t i) {
      ActiveLearner& l = learners[i];
      for (const Batch& b : batches[i]) {
        const NamedLosses losses = l.learner->train(b);
        check_finite(l.learner->learner_name(), losses);
        if (l.losses.empty())
          for (const NamedLoss& x : losses)
            l.losses.emplace_back(x.tag, Stats{});
        for (size_t k = 0; k < losses.size(); ++k)
          l.losses[k].second.add(losses[k].value);
      }
    };
    if (worker && learners.size() > 1) {
      worker->start([&] { train(0); });
      try {
        for (size_t i = 1; i < learners.size(); ++i)
          train(i);
      } catch (...) {
        worker->wait();
        throw;
      }
      worker->wait();
    } else {
      for (size_t i = 0; i < learners.size(); ++i)
        train(i);
    }
  }

  void clear_losses() {
    for (ActiveLearner& l : learners)
      for (auto& tagged : l.losses)
        tagged.second = Stats{};
  }

  void log_losses(int64_t step) {
    for (const ActiveLearner& l : learners)
      for (const auto& [tag, stats] : l.losses)
        if (stats.count) log->log(step, tag, stats.mean());
  }

  // A diverged run stops with an error: its last checkpoint (written while every number was finite) stays,
  // and no final.pt of non-finite weights is written.
  void check_finite(const char* what, const NamedLosses& losses) const {
    for (const NamedLoss& x : losses)
      check(std::isfinite(x.value),
            "training diverged at agent step {}: a {} loss is not finite (lower the learning rates?); {} "
            "keeps the last finite checkpoint, no {} is written",
            agent_steps, what, dir, kFinalFile);
  }

  bool networks_finite() const {
    std::vector<torch::Tensor> params;
    if (models.policy) params = models.policy->parameters();
    if (models.dynamics) {
      for (const auto& [key, m] : named_dynamics(models.dynamics, models.ensemble))
        for (const auto& p : m->parameters())
          params.push_back(p);
      for (const auto& p : models.reward->parameters())
        params.push_back(p);
    }
    for (const auto& p : params)
      if (!torch::isfinite(p).all().item<bool>()) return false;
    return true;
  }

  void log_if(const std::string& tag, const Stats& s) {
    if (s.count) log->log(env_steps, tag, s.mean());
  }

  void end_episode() {
    need_reset = true;
    ++episodes;
    last_return = ep_return;
    // Training time only: evaluations that ran during the episode are not part of an agent step's cost.
    const double seconds = seconds_since(ep_start) - ep_eval_seconds;
    log->log(env_steps, "train/episode_return", ep_return);
    log->log(env_steps, "train/episode_length", static_cast<double>(ep_env_steps));
    log->log(env_steps, "train/agent_steps", static_cast<double>(agent_steps));
    log->log(env_steps, "train/episodes", static_cast<double>(episodes));
    const int64_t fallbacks = controller->diagnostics().fallbacks - ep_fallbacks_start;
    log->log(env_steps, "train/fallbacks", static_cast<double>(fallbacks));
    if (const auto ok = env->episode_success()) log->log(env_steps, "train/success", *ok ? 1.0 : 0.0);
    log_if("train/mode_insertion_gradient", ep_mig);
    log_if("train/weight_ess", ep_ess);
    log_if("train/saturated_weight", ep_saturated);
    log_losses(env_steps);
    log->log(env_steps, "time/wall_seconds", wall_time());
    log->log(env_steps, "time/agent_step_ms", 1e3 * seconds / ep_agent_steps);
    log->log(env_steps, "time/act_ms", 1e3 * ep_act_seconds / ep_agent_steps);
    log->log(env_steps, "time/update_ms", 1e3 * ep_update_seconds / ep_agent_steps);
    check(ep_agent_steps < 10 || fallbacks < ep_agent_steps,
          "training diverged at agent step {}: every action of episode {} was non-finite and replaced by the "
          "fallback; {} keeps the last finite checkpoint, no {} is written",
          agent_steps, episodes, dir, kFinalFile);
    if (agent_steps >= next_checkpoint) {
      save_checkpoint();
      const int64_t every = config.get_int("checkpoint.every");
      next_checkpoint = (agent_steps / every + 1) * every;
    }
  }

  // The dynamics model's check, logged as <prefix>model_error_ratio and <prefix>model_better_components.
  void log_model_score(int64_t step, const std::string& prefix, const ModelScore& m) {
    log->log(step, prefix + "model_error_ratio", m.error_ratio);
    log->log(step, prefix + "model_better_components", m.better);
  }

  // One evaluation of `ctrl`: eval.episodes episodes from the fixed start states, logged under `label`.
  void evaluate_controller(const std::string& label, Controller& ctrl) {
    const int64_t episodes_per_eval = config.get_int("eval.episodes");
    const bool trace = config.get_bool("eval.trace");
    ControllerPolicy policy(ctrl, [this](Controller& c) { tell_interactions(c); });
    std::vector<EpisodeStats> episodes;
    TrajectoryCsv csv(eval_env->observation_dim(), eval_env->action_dim());
    // The main evaluation's transitions were never trained on: they score the dynamics model.
    const bool check_model = label.empty() && models.dynamics;
    ModelCheck model_check;
    for (int64_t e = 0; e < episodes_per_eval; ++e) {
      std::function<void(const Transition&)> on_step;
      if (trace || check_model) {
        on_step = [&](const Transition& t) {
          if (trace) csv.add(static_cast<int>(e), t);
          if (check_model && t.result.failure.empty())
            model_check.add(t.observation, t.action, t.result.observation);
        };
      }
      // The same start states at every evaluation, so curves compare like with like.
      episodes.push_back(run_episode(*eval_env, policy,
                                     derive_seed(seed, kEvalEpisode) ^ static_cast<uint64_t>(e), on_step,
                                     [&] { policy.reset(); }));
    }
    if (trace) {
      const fs::path traces = fs::path(dir) / kEvalTraceDir;
      fs::create_directories(traces);
      write_file_atomic(
          (traces / fmt::format("step{}{}.csv", env_steps, label.empty() ? "" : "_" + label)).string(),
          csv.text());
    }
    const ReturnSummary summary = summarize(episodes);
    const std::string prefix = label.empty() ? "eval/" : "eval/" + label + "_";
    log->log(env_steps, prefix + "return_mean", summary.mean_return);
    log->log(env_steps, prefix + "return_std", summary.std_return);
    if (summary.success_rate) log->log(env_steps, prefix + "success_rate", *summary.success_rate);
    if (label.empty()) last_eval = summary.mean_return;
    if (model_check.size() > 0)
      log_model_score(env_steps, "eval/", model_check.score(*models.dynamics, *eval_env));
  }

  void evaluate() {
    for (auto& [label, ctrl] : evaluators)
      evaluate_controller(label, *ctrl);
    if (!variant_evaluators.empty()) {
      at::Generator generator = at::detail::getDefaultCPUGenerator();
      const at::Tensor state = generator.get_state();
      for (auto& [label, ctrl] : variant_evaluators)
        evaluate_controller(label, *ctrl);
      generator.set_state(state);
    }
    ++evaluations;
  }

  // Imitation loop (paper Alg. 3) -------------------------------------------------------------------

  struct Recorded {
    Eigen::VectorXd s, a, s2;
    Eigen::VectorXd label;  // what imitation learns from: the policy's intended action, else a
    double r = 0;
    bool terminated = false;
  };

  // Runs one episode of `policy` on the training environment (counted in env_steps, and in agent_steps if
  // `agent` acts), keeping its transitions.
  // `after_step` runs after each step (the controller's diagnostics then describe its action).
  EpisodeStats record_episode(PolicySource& policy, uint64_t reset_seed, int max_steps, bool agent,
                              std::vector<Recorded>& out, const std::function<void()>& on_reset = {},
                              const std::function<void()>& after_step = {}) {
    out.clear();
    return run_episode(
        *env, policy, reset_seed,
        [&](const Transition& t) {
          out.push_back({t.observation, t.action, t.result.observation,
                         policy.intended_action().value_or(t.action), t.result.reward, t.result.terminated});
          env_steps += env->last_step_frames();
          if (agent) ++agent_steps;
          if (after_step) after_step();
        },
        on_reset, max_steps);
  }

  // Stores a recorded episode with a' = the next step's action; after the last step a' is what `policy`
  // does at s' (the episode was cut there), or a itself at a terminal state (masked by done). `executed`
  // gets the actions that ran (the models learn from those), `labelled` (if any) the same or, with
  // `intended`, the policy's intended actions (PolicySource::intended_action).
  void store(const std::vector<Recorded>& episode, PolicySource& policy, ReplayBuffer* executed,
             ReplayBuffer* labelled = nullptr, bool intended = false) {
    for (size_t t = 0; t < episode.size(); ++t) {
      const Recorded& x = episode[t];
      const bool last = t + 1 == episode.size();
      Eigen::VectorXd a2, label2;
      if (!last) {
        a2 = episode[t + 1].a;
        label2 = episode[t + 1].label;
      } else if (x.terminated) {
        a2 = x.a;
        label2 = x.label;
      } else {
        a2 = policy.act(x.s2);
        label2 = policy.intended_action().value_or(a2);
      }
      executed->add(x.s.data(), x.a.data(), x.r, x.s2.data(), a2.data(), x.terminated);
      if (!labelled) continue;
      if (intended) {
        labelled->add(x.s.data(), x.label.data(), x.r, x.s2.data(), label2.data(), x.terminated);
      } else {
        labelled->add(x.s.data(), x.a.data(), x.r, x.s2.data(), a2.data(), x.terminated);
      }
    }
  }

  // imitation.eval_episodes test episodes of `ctrl` from fixed start states (not stored): a success rate per
  // demonstration count needs more than Alg. 3's one test episode.
  std::vector<EpisodeStats> imitation_test_episodes(Controller& ctrl, int test_steps) {
    std::vector<EpisodeStats> out;
    ControllerPolicy p(ctrl, [this](Controller& c) { tell_interactions(c); });
    for (int64_t e = 0; e < config.get_int("imitation.eval_episodes"); ++e)
      out.push_back(run_episode(
          *eval_env, p, derive_seed(seed, kImitationEval) ^ static_cast<uint64_t>(e), {}, [&] { p.reset(); },
          test_steps));
    return out;
  }

  // One iteration: a demonstration into D_exp and D, every learner's updates, then a test episode of the
  // method's controller into D only. The policy alone and the expert are scored from the test episode's
  // start state (not stored), so the three returns of an iteration compare like with like.
  void iterate() {
    const auto t0 = Clock::now();
    const auto i = static_cast<uint64_t>(iterations);
    const std::string expert_spec = config.get_string("imitation.expert");
    const int demo_steps = static_cast<int>(config.get_int("imitation.demo_steps"));
    const int test_steps = static_cast<int>(config.get_int("imitation.test_steps"));
    // A fresh demonstrator per iteration, seeded by the iteration, so a resumed run draws what an
    // uninterrupted one does (only the random policy draws anything).
    std::unique_ptr<PolicySource> demonstrator =
        make_fixed_policy(expert_spec, *env, derive_seed(seed, kDemonstrator) ^ i, "imitation.expert");
    if (const double noise = config.get_double("imitation.demo_noise"); noise > 0)
      demonstrator = std::make_unique<NoisyPolicy>(std::move(demonstrator), noise,
                                                   derive_seed(seed, kDemonstratorNoise) ^ i);
    std::vector<Recorded> episode;
    const EpisodeStats demo = record_episode(*demonstrator, derive_seed(seed, kDemonstrationEpisode) ^ i,
                                             demo_steps, false, episode);
    store(episode, *demonstrator, buffer.get(), demonstrations.get(),
          config.get_bool("imitation.intended_labels"));

    clear_losses();
    if (config.get_bool("imitation.restart_model_optimizer")) {
      for (ActiveLearner& l : learners)
        if (std::string(l.learner->learner_name()) == "model") l.learner->restart_optimizer();
    }
    train_learners();

    const uint64_t start = derive_seed(seed, kEvalEpisode) ^ i;
    // The planner's weight diagnostics over the test episode say whether it trusted a few rollouts.
    Stats ess, saturated;
    const int64_t fallbacks_before = controller->diagnostics().fallbacks;
    ControllerPolicy tester(*controller, [this](Controller& c) { tell_interactions(c); });
    const EpisodeStats test = record_episode(
        tester, start, test_steps, true, episode, [&] { tester.reset(); },
        [&] {
          const double e = controller->diagnostics().weight_ess;
          const double sat = controller->diagnostics().saturated_weight;
          if (std::isfinite(e)) ess.add(e);
          if (std::isfinite(sat)) saturated.add(sat);
        });
    // Counted now: the extra test episodes below use the same controller.
    const int64_t test_fallbacks = controller->diagnostics().fallbacks - fallbacks_before;
    // The test episode is new to the dynamics model (it is stored just below): it scores the model.
    std::optional<ModelScore> model_score;
    if (models.dynamics) {
      ModelCheck check;
      const size_t usable = episode.size() - (test.failure.empty() || episode.empty() ? 0 : 1);
      for (size_t k = 0; k < usable; ++k)
        check.add(episode[k].s, episode[k].a, episode[k].s2);
      if (check.size() > 0) model_score = check.score(*models.dynamics, *eval_env);
    }
    store(episode, tester, buffer.get());
    ++episodes;

    EpisodeStats policy_alone = test;  // bc: the test episode is the policy alone
    if (method->controller != "policy") {
      auto alone = make_controller("policy", models, config, /*evaluation=*/true);
      ControllerPolicy p(*alone);
      policy_alone = run_episode(*eval_env, p, start, {}, {}, test_steps);
    }
    const double policy_return = policy_alone.episode_return;
    double expert_return = std::nan("");
    std::optional<bool> expert_success;
    if (config.get_bool("imitation.expert_episode")) {
      auto expert = make_fixed_policy(expert_spec, *eval_env, derive_seed(seed, kDemonstrator) ^ ~i,
                                      "imitation.expert");
      const EpisodeStats e = run_episode(*eval_env, *expert, start, {}, {}, test_steps);
      expert_return = e.episode_return;
      expert_success = e.success;
    }
    const std::vector<EpisodeStats> extra = imitation_test_episodes(*controller, test_steps);
    // eval.variants: the same test episodes with the controller built otherwise, on the same networks, with
    // the generator's state put back so that the run is unchanged.
    std::vector<std::pair<std::string, std::vector<EpisodeStats>>> variant_episodes;
    if (!variant_evaluators.empty() && !extra.empty()) {
      at::Generator generator = at::detail::getDefaultCPUGenerator();
      const at::Tensor state = generator.get_state();
      for (auto& [label, ctrl] : variant_evaluators)
        variant_episodes.emplace_back(label, imitation_test_episodes(*ctrl, test_steps));
      generator.set_state(state);
    }

    ++iterations;
    last_return = last_eval = test.episode_return;
    const int64_t step = iterations;
    log->log(step, "imitation/demonstrations", static_cast<double>(iterations));
    log->log(step, "imitation/demonstration_return", demo.episode_return);
    log->log(step, "imitation/test_return", test.episode_return);
    log->log(step, "imitation/test_length", static_cast<double>(test.length));
    log->log(step, "imitation/policy_return", policy_return);
    if (ess.count) log->log(step, "imitation/weight_ess", ess.mean());
    // Steps where the controller's action was not finite and its policy acted instead (train/fallbacks
    // of the online loop).
    log->log(step, "imitation/fallbacks", static_cast<double>(test_fallbacks));
    if (saturated.count) log->log(step, "imitation/saturated_weight", saturated.mean());
    if (model_score) log_model_score(step, "imitation/", *model_score);
    if (std::isfinite(expert_return)) log->log(step, "imitation/expert_return", expert_return);
    auto log_success = [&](const char* tag, const std::optional<bool>& ok) {
      if (ok) log->log(step, tag, *ok ? 1.0 : 0.0);
    };
    log_success("imitation/test_success", test.success);
    log_success("imitation/policy_success", policy_alone.success);
    log_success("imitation/expert_success", expert_success);
    if (!extra.empty()) {
      const ReturnSummary s = summarize(extra);
      log->log(step, "imitation/eval_return_mean", s.mean_return);
      log->log(step, "imitation/eval_return_std", s.std_return);
      if (s.success_rate) log->log(step, "imitation/eval_success_rate", *s.success_rate);
    }
    for (const auto& [label, episodes] : variant_episodes) {
      const ReturnSummary s = summarize(episodes);
      log->log(step, "imitation/" + label + "_return_mean", s.mean_return);
      log->log(step, "imitation/" + label + "_return_std", s.std_return);
      if (s.success_rate) log->log(step, "imitation/" + label + "_success_rate", *s.success_rate);
    }
    // Not train/agent_steps: that tag counts an online run's progress (the sweep engine reads it).
    log->log(step, "imitation/agent_steps", static_cast<double>(agent_steps));
    log->log(step, "imitation/env_steps", static_cast<double>(env_steps));
    log_losses(step);
    log->log(step, "time/wall_seconds", wall_time());
    log->log(step, "time/iteration_seconds", seconds_since(t0));
    // Every iteration ends at an episode boundary: a checkpoint each time.
    save_checkpoint();
  }

  // The step axis of the log: environment steps (online loop) or iterations (imitation loop).
  int64_t log_step() const { return imitation ? iterations : env_steps; }

  std::string path(const char* file) const { return (fs::path(dir) / file).string(); }

  // What a tool needs to run the trained networks: config, counters, policy architecture and weights.
  void add_networks(CheckpointWriter& w) const {
    w.add_string("config", config.to_yaml());
    w.add_string("env", config.get_string("env"));
    w.add_string("method", config.get_string("method"));
    w.add_int("frame_skip", config.get_int("train.frame_skip"));
    w.add_int("agent_steps", agent_steps);
    w.add_int("env_steps", env_steps);
    w.add_int("episodes", episodes);
    w.add_int("evaluations", evaluations);
    w.add_int("next_checkpoint", next_checkpoint);
    w.add_tensor("wall_seconds", torch::tensor({wall_time()}, torch::kFloat64));
    if (imitation) w.add_int("iterations", iterations);
    if (models.policy) {
      // Enough to rebuild the policy without the run's config (hlt_rollout --policy checkpoint:PATH).
      w.add_tensor("policy_hidden", torch::tensor(config.get_int_list("policy.hidden"), torch::kInt64));
      w.add_string("policy_activation", config.get_string("policy.activation"));
      const GaussianPolicyOptions& po = models.policy->options();
      if (!po.input_scale.empty()) {
        w.add_tensor("policy_input_offset", torch::tensor(po.input_offset, torch::kFloat64));
        w.add_tensor("policy_input_scale", torch::tensor(po.input_scale, torch::kFloat64));
        if (!po.input_reference.empty())
          w.add_tensor("policy_input_reference", torch::tensor(po.input_reference, torch::kInt64));
      }
      w.add_module("policy", *models.policy);
    }
    if (models.dynamics) {
      for (const auto& [key, m] : named_dynamics(models.dynamics, models.ensemble))
        w.add_module(key, *m);
      w.add_module("reward", *models.reward);
    }
  }

  // Everything a resumed run needs; written only at episode ends, where no transition is pending.
  void save_checkpoint() {
    check(
        networks_finite(),
        "training diverged at agent step {}: the networks hold non-finite weights; {} keeps the last finite "
        "checkpoint, no {} is written",
        agent_steps, dir, kFinalFile);
    CheckpointWriter w;
    add_networks(w);
    w.add_tensor("torch_rng", at::detail::getDefaultCPUGenerator().get_state());
    for (const ActiveLearner& l : learners)
      l.learner->save_training_state(w);
    buffer->save(w.archive(kReplayData));
    if (demonstrations) demonstrations->save(w.archive(kDemonstrationData));
    w.save(path(kCheckpointFile));
  }

  // The networks at the end of the run (which may end mid-episode), for rollouts and evaluation.
  void save_final() {
    check(networks_finite(), "training diverged: the networks hold non-finite weights; {} is not written",
          kFinalFile);
    CheckpointWriter w;
    add_networks(w);
    w.save(path(kFinalFile));
  }

  void load_checkpoint() {
    CheckpointReader r(path(kCheckpointFile));
    for (const char* key : {"env", "method"}) {
      check(r.get_string(key) == config.get_string(key),
            "{}: checkpoint was written by {} '{}', config says '{}'", dir, key, r.get_string(key),
            config.get_string(key));
    }
    // Everything but the step budget must match the run that wrote the checkpoint.
    Config stored = make_train_config();
    stored.merge_yaml(r.get_string("config"), r.path());
    for (const char* budget : {"train.agent_steps", "imitation.iterations"})
      stored.set(budget, std::to_string(config.get_int(budget)));
    check(stored.to_yaml() == config.to_yaml(), "{}: {} does not match the checkpoint's config", dir,
          kConfigFile);
    agent_steps = r.get_int("agent_steps");
    env_steps = r.get_int("env_steps");
    episodes = r.get_int("episodes");
    evaluations = r.get_int("evaluations");
    next_checkpoint = r.get_int("next_checkpoint");
    wall_before = r.tensor("wall_seconds").item<double>();
    at::Generator generator = at::detail::getDefaultCPUGenerator();
    generator.set_state(r.tensor("torch_rng"));
    if (models.policy) r.load_module("policy", *models.policy);
    if (models.dynamics) {
      for (auto [key, m] : named_dynamics(models.dynamics, models.ensemble))
        r.load_module(key, *m);
      r.load_module("reward", *models.reward);
    }
    for (ActiveLearner& l : learners)
      l.learner->load_training_state(r);
    buffer->load(r.archive(kReplayData));
    if (demonstrations) demonstrations->load(r.archive(kDemonstrationData));
    if (imitation) iterations = r.get_int("iterations");
  }
};

Trainer::Trainer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

std::string Trainer::budget_key(const Config& config) {
  return find_method(config.get_string("method")).loop == kImitationLoop ? "imitation.iterations"
                                                                         : "train.agent_steps";
}
Trainer::~Trainer() = default;

const Config& Trainer::config() const {
  return impl_->config;
}
const std::string& Trainer::run_dir() const {
  return impl_->dir;
}
Trainer::Summary Trainer::summary() const {
  return {impl_->agent_steps, impl_->env_steps, impl_->last_eval, impl_->last_return,
          impl_->imitation ? impl_->iterations : -1};
}

std::unique_ptr<Trainer> Trainer::create(const Config& config, const std::string& run_dir) {
  ensure_writable_directory(run_dir);
  auto lock = std::make_unique<DirectoryLock>(run_dir);
  for (const char* f : {kConfigFile, kLogFile, kCheckpointFile, kFinalFile}) {
    check(!fs::exists(fs::path(run_dir) / f),
          "{} already holds a run ({} exists); resume it with --resume {} or "
          "choose another --out",
          run_dir, f, run_dir);
  }
  for (const auto& entry : fs::directory_iterator(run_dir)) {
    const std::string name = entry.path().filename().string();
    check(name.rfind("events.out.tfevents.", 0) != 0,
          "{} already holds TensorBoard event files ({}) of another run; choose another --out", run_dir,
          name);
  }
  remove_stale_temporaries(run_dir);
  auto impl = std::make_unique<Impl>();
  impl->lock = std::move(lock);
  impl->config = config;
  impl->dir = run_dir;
  impl->build();
  impl->config.save(impl->path(kConfigFile), run_notes());
  impl->log = std::make_unique<ScalarLogger>(impl->path(kLogFile));
  return std::unique_ptr<Trainer>(new Trainer(std::move(impl)));
}

std::unique_ptr<Trainer> Trainer::resume(const std::string& run_dir, std::optional<int64_t> agent_steps) {
  const fs::path cfg = fs::path(run_dir) / kConfigFile;
  check(fs::is_directory(run_dir), "--resume {}: no such directory", run_dir);
  check(fs::exists(cfg), "--resume {}: not a run directory ({} is missing)", run_dir, kConfigFile);
  auto impl = std::make_unique<Impl>();
  impl->lock = std::make_unique<DirectoryLock>(run_dir);
  remove_stale_temporaries(run_dir);
  if (fs::is_directory(fs::path(run_dir) / kEvalTraceDir))
    remove_stale_temporaries((fs::path(run_dir) / kEvalTraceDir).string());
  impl->dir = run_dir;
  impl->config = make_train_config();
  impl->config.load_file(cfg.string());
  if (agent_steps) impl->config.set(budget_key(impl->config), std::to_string(*agent_steps), "--steps");
  impl->build();
  const std::string log_path = impl->path(kLogFile);
  if (fs::exists(impl->path(kCheckpointFile))) {
    impl->load_checkpoint();
    const int64_t done = impl->imitation ? impl->iterations : impl->agent_steps;
    check(!agent_steps || *agent_steps >= done,
          "--resume {} --steps {}: the run has trained {} {} already; a smaller budget would discard them "
          "(copy the run and shorten the copy's log instead)",
          run_dir, agent_steps.value_or(0), done, impl->imitation ? "iterations" : "agent steps");
    if (fs::exists(log_path)) ScalarLogger::truncate_after(log_path, impl->log_step());
  } else {
    // Only a run killed before its first checkpoint may start over: anything else lost its checkpoint.
    check(!fs::exists(impl->path(kFinalFile)),
          "--resume {}: {} is missing but {} exists (the run finished, then its checkpoint was removed); "
          "it cannot be resumed",
          run_dir, kCheckpointFile, kFinalFile);
    if (fs::exists(log_path)) {
      int64_t logged_agent_steps = 0;
      for (const auto& row : ScalarLogger::read(log_path))
        if (row.tag == "train/agent_steps") logged_agent_steps = static_cast<int64_t>(row.value);
      check(logged_agent_steps < impl->config.get_int("checkpoint.every"),
            "--resume {}: {} is missing although the log reaches agent step {} (past the first checkpoint "
            "at {}); it cannot be resumed without losing the log",
            run_dir, kCheckpointFile, logged_agent_steps, impl->config.get_int("checkpoint.every"));
      // Killed before its first checkpoint: start over, keeping nothing the new run would not write again.
      ScalarLogger::truncate_after(log_path, -1);
    }
  }
  const std::string notes = run_notes();
  const std::string old_config = read_file(cfg.string());
  if (old_config.rfind("# " + notes + "\n", 0) != 0) {
    fmt::print(stderr,
               "warning: {}'s {} records another BLAS kernel or vector instruction set; the resumed part's "
               "numbers may "
               "differ in their last digits from an uninterrupted run's\n  now: {}\n",
               run_dir, kConfigFile, notes);
  }
  impl->config.save(cfg.string(), notes);
  impl->log = std::make_unique<ScalarLogger>(log_path);
  return std::unique_ptr<Trainer>(new Trainer(std::move(impl)));
}

void Trainer::run(bool progress) {
  Impl& s = *impl_;
  const int64_t total = s.config.get_int("train.agent_steps");
  if (!s.imitation && s.agent_steps >= total) {
    fmt::print(stderr, "{}: already trained for {} agent steps\n", s.dir, s.agent_steps);
    // Killed while final.pt was written: the checkpoint holds the same networks.
    if (!fs::exists(s.path(kFinalFile))) s.save_final();
    return;
  }
  if (s.imitation) {
    const int64_t iterations = s.config.get_int("imitation.iterations");
    if (s.iterations >= iterations) {
      fmt::print(stderr, "{}: already ran {} iterations\n", s.dir, s.iterations);
      if (!fs::exists(s.path(kFinalFile))) s.save_final();
      return;
    }
    ProgressBar bar(s.iterations, iterations, progress);
    while (s.iterations < iterations) {
      s.iterate();
      bar.set("return", s.last_return);
      bar.update(s.iterations);
    }
    bar.finish();
    s.save_final();
    return;
  }
  ProgressBar bar(s.agent_steps, total, progress);
  if (s.agent_steps == 0 && s.eval_every > 0) s.evaluate();
  while (s.agent_steps < total) {
    s.step();
    bar.set("return", s.last_return);
    bar.set("eval", s.last_eval);
    bar.update(s.agent_steps);
  }
  bar.finish();
  // A final evaluation if the last step did not just have one; the final checkpoint only at an episode end,
  // so that a resumed (extended) run continues exactly.
  if (s.eval_every > 0 && s.agent_steps % s.eval_every != 0) s.evaluate();
  if (s.need_reset) s.save_checkpoint();
  s.save_final();
}

}  // namespace hlt
