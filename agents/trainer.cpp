#include "agents/trainer.h"

#include <ATen/CPUGeneratorImpl.h>
#include <torch/torch.h>

#include <chrono>
#include <cmath>
#include <filesystem>

#include "agents/controller_policy.h"
#include "agents/methods.h"
#include "agents/model_learner.h"
#include "agents/sac.h"
#include "agents/train_config.h"
#include "envs/registry.h"
#include "hlt/control/deterministic_hybrid.h"
#include "hlt/core/checkpoint.h"
#include "hlt/core/runtime.h"
#include "hlt/data/replay_buffer.h"
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

// Seed streams derived from the run seed (see derive_seed).
enum Stream : uint64_t { kReplay = 1, kTrainEpisode = 2, kEvalEpisode = 3, kSacNoise = 4 };

// The header of config.yaml: what the run's numbers depend on besides its settings. The same seed gives
// the same numbers only with the same BLAS kernel.
std::string run_notes() {
  return "blas: " + blas_kernel().summary();
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
  std::unique_ptr<Sac> sac;
  std::unique_ptr<ModelLearner> learner;
  std::unique_ptr<ReplayBuffer> buffer;
  std::unique_ptr<Controller> controller;
  std::vector<std::pair<std::string, std::unique_ptr<Controller>>> evaluators;  // label, controller
  std::unique_ptr<ScalarLogger> log;
  std::unique_ptr<WorkerThread> worker;  // train.threads = 2: runs the SAC updates beside the model updates

  // Per-step settings, read from the config once.
  int64_t update_after = 0, batch_size = 0, sac_updates = 0, model_updates = 0, eval_every = 0;

  // Counters (checkpointed).
  int64_t agent_steps = 0, env_steps = 0, episodes = 0, evaluations = 0;
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
  Stats ep_mig, ep_ess, ep_saturated, critic_loss, actor_loss, alpha, entropy, dyn_loss, rew_loss;
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

    if (method->trains_policy) {
      GaussianPolicyOptions po;
      po.state_dim = n;
      po.action_dim = m;
      po.hidden = config.get_int_list("policy.hidden");
      po.mean_activation = parse_activation(config.get_string("policy.activation"));
      models.policy = GaussianPolicy(po);
      SacOptions so;
      so.gamma = config.get_double("sac.gamma");
      so.tau = config.get_double("sac.tau");
      so.q_lr = so.policy_lr = so.alpha_lr = config.get_double("sac.lr");
      if (config.get_double("sac.policy_lr") > 0) so.policy_lr = config.get_double("sac.policy_lr");
      if (config.get_double("sac.alpha_lr") > 0) so.alpha_lr = config.get_double("sac.alpha_lr");
      so.q_hidden = config.get_int_list("sac.q_hidden");
      so.initial_alpha = config.get_double("sac.initial_alpha");
      so.seed = derive_seed(seed, kSacNoise);
      sac = std::make_unique<Sac>(models.policy, n, m, so);
    }
    if (method->trains_models) {
      models.dynamics = DynamicsModel(DynamicsModelOptions{
          n, m, config.get_int("model.hidden"), parse_activation(config.get_string("model.activation"))});
      models.reward = RewardModel(RewardModelOptions{n, m, config.get_int("model.reward_hidden")});
      ModelLearnerOptions mo;
      mo.lr = config.get_double("model.lr");
      mo.reward_gamma = config.get_double("model.reward_gamma");
      mo.reward_weight = config.get_double("model.reward_weight");
      learner = std::make_unique<ModelLearner>(models.dynamics, models.reward, mo);
    }
    buffer = std::make_unique<ReplayBuffer>(config.get_int("train.replay_capacity"), n, m,
                                            derive_seed(seed, kReplay));
    controller = make_controller(method->controller, models, config, /*evaluation=*/false);
    evaluators.emplace_back("", make_controller(method->controller, models, config, /*evaluation=*/true));
    if (config.get_bool("eval.components") && method->trains_policy && method->trains_models) {
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
    next_checkpoint = config.get_int("checkpoint.every");
    update_after = config.get_int("train.update_after");
    batch_size = config.get_int("train.batch_size");
    sac_updates = config.get_int("train.sac_updates");
    model_updates = config.get_int("train.model_updates");
    eval_every = config.get_int("eval.every");
    if (config.get_int("train.threads") > 1 && sac && learner) worker = std::make_unique<WorkerThread>();
  }

  // Exploration decays with agent steps (calls to the environment's step), as in the authors' code.
  void tell_interactions(Controller& c) const {
    if (auto* det = dynamic_cast<DeterministicHybrid*>(&c)) det->set_interactions(agent_steps);
  }

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
    ep_mig = ep_ess = ep_saturated = critic_loss = actor_loss = alpha = entropy = dyn_loss = rew_loss =
        Stats{};
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

  // An agent step's learner updates. Every batch is drawn first (SAC's, then the models'), and SAC's policy
  // samples come from its own generator; the two learners share no parameters, so running them
  // concurrently (train.threads = 2) computes exactly what running them one after the other does.
  void update() {
    if (buffer->size() < update_after) return;
    std::vector<Batch> sac_batches, model_batches;
    for (int64_t i = 0; sac && i < sac_updates; ++i)
      sac_batches.push_back(buffer->sample(batch_size));
    for (int64_t i = 0; learner && i < model_updates; ++i)
      model_batches.push_back(buffer->sample(batch_size));
    auto update_sac = [&] {
      for (const Batch& b : sac_batches) {
        const SacLosses l = sac->update(b);
        check_finite("SAC", {l.critic, l.actor, l.alpha});
        critic_loss.add(l.critic);
        actor_loss.add(l.actor);
        alpha.add(l.alpha);
        entropy.add(l.entropy);
      }
    };
    auto update_models = [&] {
      for (const Batch& b : model_batches) {
        const ModelLosses l = learner->update(b);
        check_finite("model", {l.dynamics, l.reward});
        dyn_loss.add(l.dynamics);
        rew_loss.add(l.reward);
      }
    };
    if (worker) {
      worker->start(update_sac);
      try {
        update_models();
      } catch (...) {
        worker->wait();
        throw;
      }
      worker->wait();
    } else {
      update_sac();
      update_models();
    }
  }

  // A diverged run stops with an error: its last checkpoint (written while every number was finite) stays,
  // and no final.pt of non-finite weights is written.
  void check_finite(const char* what, std::initializer_list<double> losses) const {
    for (double x : losses)
      check(std::isfinite(x),
            "training diverged at agent step {}: a {} loss is not finite (lower the learning rates?); {} "
            "keeps the last finite checkpoint, no {} is written",
            agent_steps, what, dir, kFinalFile);
  }

  bool networks_finite() const {
    std::vector<torch::Tensor> params;
    if (models.policy) params = models.policy->parameters();
    if (models.dynamics) {
      for (const auto& p : models.dynamics->parameters())
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
    log_if("train/mode_insertion_gradient", ep_mig);
    log_if("train/weight_ess", ep_ess);
    log_if("train/saturated_weight", ep_saturated);
    log_if("loss/critic", critic_loss);
    log_if("loss/actor", actor_loss);
    log_if("sac/alpha", alpha);
    log_if("sac/entropy", entropy);
    log_if("loss/dynamics", dyn_loss);
    log_if("loss/reward", rew_loss);
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

  void evaluate() {
    const int64_t episodes_per_eval = config.get_int("eval.episodes");
    for (auto& [label, ctrl] : evaluators) {
      ControllerPolicy policy(*ctrl, [this](Controller& c) { tell_interactions(c); });
      std::vector<EpisodeStats> episodes;
      for (int64_t e = 0; e < episodes_per_eval; ++e) {
        // The same start states at every evaluation, so curves compare like with like.
        episodes.push_back(run_episode(*eval_env, policy,
                                       derive_seed(seed, kEvalEpisode) ^ static_cast<uint64_t>(e), {},
                                       [&] { policy.reset(); }));
      }
      const ReturnSummary summary = summarize(episodes);
      const std::string prefix = label.empty() ? "eval/" : "eval/" + label + "_";
      log->log(env_steps, prefix + "return_mean", summary.mean_return);
      log->log(env_steps, prefix + "return_std", summary.std_return);
      if (label.empty()) last_eval = summary.mean_return;
    }
    ++evaluations;
  }

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
    if (models.policy) {
      // Enough to rebuild the policy without the run's config (hlt_rollout --policy checkpoint:PATH).
      w.add_tensor("policy_hidden", torch::tensor(config.get_int_list("policy.hidden"), torch::kInt64));
      w.add_string("policy_activation", config.get_string("policy.activation"));
      w.add_module("policy", *models.policy);
    }
    if (models.dynamics) {
      w.add_module("dynamics", *models.dynamics);
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
    if (sac) sac->save_training_state(w);
    if (learner) learner->save_training_state(w);
    buffer->save(w.archive("replay"));
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
    stored.set("train.agent_steps", std::to_string(config.get_int("train.agent_steps")));
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
      r.load_module("dynamics", *models.dynamics);
      r.load_module("reward", *models.reward);
    }
    if (sac) sac->load_training_state(r);
    if (learner) learner->load_training_state(r);
    buffer->load(r.archive("replay"));
  }
};

Trainer::Trainer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Trainer::~Trainer() = default;

const Config& Trainer::config() const {
  return impl_->config;
}
const std::string& Trainer::run_dir() const {
  return impl_->dir;
}
Trainer::Summary Trainer::summary() const {
  return {impl_->agent_steps, impl_->env_steps, impl_->last_eval, impl_->last_return};
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
  impl->dir = run_dir;
  impl->config = make_train_config();
  impl->config.load_file(cfg.string());
  if (agent_steps) impl->config.set("train.agent_steps", std::to_string(*agent_steps), "--steps");
  impl->build();
  const std::string log_path = impl->path(kLogFile);
  if (fs::exists(impl->path(kCheckpointFile))) {
    impl->load_checkpoint();
    check(!agent_steps || *agent_steps >= impl->agent_steps,
          "--resume {} --steps {}: the run has trained {} agent steps already; a smaller budget would "
          "discard them (copy the run and shorten the copy's log instead)",
          run_dir, agent_steps.value_or(0), impl->agent_steps);
    if (fs::exists(log_path)) ScalarLogger::truncate_after(log_path, impl->env_steps);
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
               "warning: {}'s {} records another BLAS kernel or none; the resumed part's numbers may "
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
  if (s.agent_steps >= total) {
    fmt::print(stderr, "{}: already trained for {} agent steps\n", s.dir, s.agent_steps);
    // Killed while final.pt was written: the checkpoint holds the same networks.
    if (!fs::exists(s.path(kFinalFile))) s.save_final();
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
