#include "agents/train_config.h"

#include <filesystem>

#include "agents/methods.h"
#include "envs/registry.h"

namespace hlt {

Config make_train_config() {
  Config c;
  const int64_t big = 1'000'000'000;
  c.add_string("env", "cartpole_swingup", "environment name", env_names())
      .add_string("method", "hybrid-stochastic", "training method", method_names())
      .add_int("seed", 0, "run seed (torch, replay sampling, environment resets, evaluation)", 0, big)
      .add_int("threads", 1, "LibTorch intra-op threads (1 is fastest for these networks and reproducible)",
               1, 64)
      .add_int("train.agent_steps", 10000, "agent steps to train for (each is frame_skip simulator steps)", 1,
               big)
      .add_int("train.frame_skip", 4,
               "simulator steps per agent step (the action is repeated, rewards summed)", 1, 100)
      .add_int("train.batch_size", 128, "minibatch size for every update", 1, 65536)
      .add_int("train.update_after", 128, "transitions stored before updates start", 1, big)
      .add_int("train.sac_updates", 1, "SAC updates per agent step", 0, 100)
      .add_int("train.model_updates", 5, "dynamics + reward model updates per agent step", 0, 100)
      .add_int("train.threads", 1,
               "threads for an agent step's learner updates: 2 runs the SAC update and the model updates "
               "concurrently (the same numbers as 1)",
               1, 2)
      .add_int("train.replay_capacity", 1000000, "replay buffer capacity (transitions)", 1, 100000000)
      .add_int("eval.every", 1000, "agent steps between evaluations (0: never)", 0, big)
      .add_int("eval.episodes", 5, "episodes per evaluation", 1, 1000)
      .add_bool(
          "eval.components", true,
          "for hybrid methods also evaluate the policy alone and the model-based planner alone (Fig. 4)")
      .add_bool("eval.trace", false,
                "write every evaluation's episodes step by step (observation, action, reward) to "
                "<run>/eval_traces/step<env steps>[_policy|_planner].csv")
      .add_bool("eval.compare_density", false,
                "diagnostic for hybrid-stochastic: also evaluate the same networks with the other p(v) "
                "(planner.density_tanh_correction toggled), logged as eval/other_density_return_mean")
      .add_string(
          "eval.variants", "",
          "diagnostic: ';'-separated sets of space-separated key=value overrides; each set is one more "
          "evaluation of the method's controller built with those overrides, logged as "
          "eval/variant<i>_return_mean (imitation loop: imitation/variant<i>_return_mean and "
          "_success_rate over the imitation.eval_episodes test episodes). The variants run with the random "
          "number generator's state "
          "restored afterwards, so they change none of the run's other numbers")
      .add_int("checkpoint.every", 5000, "agent steps between checkpoints (written at the next episode end)",
               1, big)
      .add_string("imitation.expert", "",
                  "imitation methods: the demonstrator, expert:PATH (agents/experts/) or a simple policy "
                  "(zero, random, constant:V); hlt_train looks a relative path up from the working "
                  "directory, then from "
                  "the repository")
      .add_int("imitation.iterations", 10, "imitation methods: iterations, one demonstration each (Alg. 3)",
               1, 100000)
      .add_int("imitation.demo_steps", 200, "imitation methods: agent steps per demonstration", 1, 1000000)
      .add_int("imitation.test_steps", 400,
               "imitation methods: agent steps of each test episode (0: the environment's own limit)", 0,
               1000000)
      .add_int("imitation.policy_updates", 500,
               "imitation methods: behaviour-cloning updates per iteration (batches from D_exp)", 0, 1000000)
      .add_int("imitation.model_updates", 500,
               "imitation methods: dynamics + reward model updates per iteration (batches from D)", 0,
               1000000)
      .add_bool("imitation.restart_model_optimizer", false,
                "imitation methods: start the models' optimizer afresh (moments forgotten, weights kept) "
                "before each iteration's updates")
      .add_bool("imitation.intended_labels", false,
                "imitation methods: behaviour cloning learns from a noisy demonstrator's noiseless action "
                "where it has one (the scripted experts; DART), not from the executed action; the models "
                "always learn from the executed one")
      .add_double("imitation.demo_noise", 0.0,
                  "imitation methods: standard deviation of Gaussian noise added to the demonstrator's "
                  "executed actions (clipped to [-1, 1]; with imitation.intended_labels behaviour cloning "
                  "learns the noiseless ones): the models then see other actions than the expert's",
                  0.0, 10.0)
      .add_bool("imitation.expert_episode", true,
                "imitation methods: also run the demonstrator from each test episode's start and log "
                "imitation/expert_return (the expert's level in the same episode)")
      .add_int("imitation.eval_episodes", 0,
               "imitation methods: extra test episodes of the method's controller after each iteration, from "
               "fixed start states and not stored (imitation/eval_return_mean, imitation/eval_success_rate)",
               0, 100000)
      .add_double("bc.lr", 0.01, "Adam learning rate of behaviour cloning", 1e-8, 1.0)
      .add_bool("bc.censor_saturated", true,
                "an expert action at the bound of the range is a censored observation (the expert asked for "
                "at least that much), not a density at the bound")
      .add_double(
          "bc.weight_decay", 0.0,
          "L2 penalty on the policy's weight matrices in behaviour cloning (0: none, the paper's loss)", 0.0,
          1.0)
      .add_double(
          "bc.input_noise", 0.0,
          "behaviour cloning: Gaussian noise on each batch's states, in units of the batch's standard "
          "deviation of each component (0: none)",
          0.0, 10.0)
      .add_int("model.hidden", 200, "dynamics model hidden width", 1, 100000)
      .add_string("model.activation", "sin", "dynamics model hidden activation", {"sin", "relu"})
      .add_int("model.reward_hidden", 200, "reward model hidden width (two layers)", 1, 100000)
      .add_double("model.lr", 3e-3, "Adam learning rate of the models", 1e-8, 1.0)
      .add_double("model.reward_gamma", 0.95,
                  "discount of the reward model's TD target (0: plain regression)", 0.0, 1.0)
      .add_string(
          "model.reward_input", "state",
          "what the reward model reads: the state a step starts from, r(s, a), or the state it reaches, "
          "r(s', a) (for rewards defined on the observation a step returns; needs model.reward_gamma 0; "
          "stochastic planners only)",
          {"state", "next_state"})
      .add_double("model.reward_weight", 0.5, "weight of the reward TD loss in the joint model loss", 0.0,
                  1000.0)
      .add_double("model.weight_decay", 0.0,
                  "L2 penalty on the dynamics model's weight matrices (0: none, the paper's loss)", 0.0, 1.0)
      .add_int("model.rollout_steps", 1,
               "steps of the dynamics loss: 1, the one-step likelihood (the paper's); K > 1, the mean "
               "likelihood of K open-loop predictions along sequences of K consecutive transitions",
               1, 1000)
      .add_int(
          "model.hard_mining", 1,
          "dynamics model: each update draws this many times train.batch_size transitions and fits the "
          "dynamics to the train.batch_size of them it predicts worst (online hard-example mining; the "
          "reward model keeps a uniform batch; 1: uniform batches, the paper's; needs model.rollout_steps 1)",
          1, 64)
      .add_int("model.ensemble", 1,
               "dynamics models trained side by side from their own initial weights on the same batches "
               "(1: the paper's single model); the stochastic planners predict with their mean and can "
               "penalise their disagreement (planner.disagreement_penalty), the deterministic ones need 1",
               1, 100)
      .add_bool("model.normalize_inputs", false,
                "the dynamics and reward models see the state as policy.normalize_inputs shows it to the "
                "policy (the environment's declared observation ranges); the dynamics' residual stays raw")
      .add_int_list("policy.hidden", {128}, "policy hidden layer widths (both heads)", 1, 100000)
      .add_string("policy.activation", "sin", "policy mean head hidden activation", {"sin", "relu"})
      .add_bool("policy.normalize_inputs", false,
                "the policy sees (s - offset) / scale with the environment's declared observation ranges "
                "(for observations mixing metres and newtons; the robot tasks declare them)")
      .add_double("sac.gamma", 0.99, "SAC discount", 0.0, 1.0)
      .add_double("sac.tau", 0.005, "SAC target critic Polyak factor", 0.0, 1.0)
      .add_double("sac.lr", 3e-4,
                  "Adam learning rate of the critics (and of policy and temperature unless set)", 1e-8, 1.0)
      .add_double("sac.policy_lr", 0.0, "Adam learning rate of the policy (0: sac.lr)", 0.0, 1.0)
      .add_double("sac.alpha_lr", 0.0, "Adam learning rate of the entropy temperature (0: sac.lr)", 0.0, 1.0)
      .add_int_list("sac.q_hidden", {256, 256}, "critic hidden layer widths", 1, 100000)
      .add_double("sac.initial_alpha", 1.0, "initial entropy temperature", 1e-8, 1e4)
      .add_double(
          "sac.bc_weight", 0.0,
          "weight of a behaviour-cloning term -log pi(a|s) on the stored (executed) actions in SAC's actor "
          "loss: with a hybrid the policy also learns the planner's choices (0: SAC as published)",
          0.0, 1000.0)
      .add_int("planner.horizon", 5, "planning horizon H (agent steps)", 1, 1000)
      .add_int("planner.samples", 20, "rollouts K of the stochastic planners", 1, 100000)
      .add_double("planner.lambda", 0.1, "temperature lambda of the stochastic planners", 1e-9, 1e12)
      .add_int(
          "planner.plan_samples", 20,
          "hybrid-stochastic: extra rollouts drawn around the warm-started plan with NN-MPPI's noise "
          "(mppi.sigma, mppi.filter) next to the planner.samples policy rollouts, every sample weighted by "
          "exp(J / lambda) (0: policy rollouts only, the paper's Alg. 2)",
          0, 100000)
      .add_bool("planner.plan_noise_from_policy", false,
                "hybrid-stochastic with plan samples: each plan sample's noise std is min(mppi.sigma, the "
                "policy's std exp(log_std(s)) at that sample's state), per step and action dimension, so "
                "the plan is searched no wider than the policy is unsure (false: mppi.sigma throughout)")
      .add_bool(
          "planner.plan_prior", false,
          "with plan samples: weight every sample by exp(J / lambda) pi(v | s), the policy's density at "
          "the sample's state (Theorem 2's bound to the policy), instead of exp(J / lambda) alone")
      .add_bool("planner.mean_rollout", false,
                "hybrid-stochastic: the first policy rollout follows the policy's mean action instead of a "
                "draw, so the planner can choose the policy's own action")
      .add_bool("planner.average_before_squash", false,
                "hybrid-stochastic: the plan averages the weighted samples before the policy's tanh, "
                "a = tanh(sum_k w_k atanh(v_k)), instead of the squashed actions, sum_k w_k v_k (the "
                "paper's); with weights the models cannot sharpen this stays near the policy's own action")
      .add_bool(
          "planner.clamp_to_data", false,
          "stochastic planners (hybrid-stochastic, NN-MPPI): keep the predicted states inside the range "
          "of the states the dynamics model was trained on (per dimension), so the planner does not act "
          "on the model's extrapolation beyond its data")
      .add_double(
          "planner.terminal_value", 0.0,
          "hybrid-stochastic: add this weight times SAC's critic at each sample's last predicted state, "
          "min(Q1, Q2)(s_H, tanh(mu(s_H))), to its predicted return (0: the paper's rule, no value "
          "beyond the horizon)",
          0.0, 1e6)
      .add_double("planner.disagreement_penalty", 0.0,
                  "stochastic planners with model.ensemble > 1: every predicted step's reward loses this "
                  "times the ensemble's disagreement on the next state, in units of the model's noise "
                  "scale (0: none; the members' mean is used either way)",
                  0.0, 1e6)
      .add_bool("planner.density_in_weights", true, "include log p(v) in the stochastic planner's weights")
      .add_double("planner.min_ess_fraction", 0.0,
                  "if > 0, temper a step's J / lambda so its weights' effective sample size is at least this "
                  "fraction of planner.samples (0: the paper's weights)",
                  0.0, 1.0)
      .add_bool("planner.density_tanh_correction", false,
                "hybrid-stochastic: p(v) is the density of the squashed action tanh(u) (adds -log(1 - v^2)) "
                "instead of the policy's Gaussian N(mu, Sigma) at u = atanh(v) (false: the authors' choice)")
      .add_double("mppi.sigma", 0.3, "NN-MPPI noise standard deviation", 1e-6, 10.0)
      .add_double("mppi.filter", 0.5, "NN-MPPI low-pass filter coefficient (eta = f eta + (1 - f) eps)", 0.0,
                  0.999)
      .add_bool("deterministic.clamp_adjoint", false,
                "exact rule: clamp rho to [-1, 1] before use (the bounded rule always clamps)")
      .add_string(
          "deterministic.action_rule", "bounded",
          "hybrid-deterministic's a*: 'exact' = mu + Sigma (dr/da_0 + B_0^T rho_1) (Theorem 1, discrete); "
          "'bounded' = clip(mu_raw + Sigma (1 - tanh^2 mu_raw) B_0^T clamp(rho_0, -1, 1)) (the authors' "
          "rule); 'squashed' = tanh(mu_raw + the same bounded correction) (zero correction is the policy's "
          "action; see DeterministicActionRule). The model-based baseline always uses 'exact'",
          {"bounded", "exact", "squashed"})
      .add_string(
          "deterministic.exploration", "policy",
          "hybrid-deterministic's training noise: 'policy' = a draw of the policy's own Gaussian in "
          "place of its mean inside the action rule, so that zero correction executes what SAC would; "
          "'decay' = N(0, exploration_decay^t) added to a* (the authors'; see DeterministicExploration). "
          "The model-based baseline always uses 'decay'",
          {"decay", "policy"})
      .add_double(
          "deterministic.exploration_decay", 0.999,
          "deterministic.exploration=decay (and the model-based baseline): noise std = decay^t, t counting "
          "agent steps (environment interactions)",
          0.0, 1.0);
  return c;
}

namespace {

void load_if_present(Config& config, const std::filesystem::path& file) {
  if (std::filesystem::exists(file)) config.load_file(file.string());
}

}  // namespace

void load_env_defaults(Config& config, const std::string& config_dir, const std::string& env) {
  load_if_present(config, std::filesystem::path(config_dir) / (env + ".yaml"));
}

void load_method_overlay(Config& config, const std::string& config_dir, const std::string& method,
                         const std::string& env) {
  const auto methods = std::filesystem::path(config_dir) / "methods";
  load_if_present(config, methods / (method + ".yaml"));
  load_if_present(config, methods / method / (env + ".yaml"));
}

}  // namespace hlt
