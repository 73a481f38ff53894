// The hybrid controllers against finite differences, closed forms and problems with known answers.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <functional>

#include "hlt/control/action_sampler.h"
#include "hlt/control/deterministic_hybrid.h"
#include "hlt/control/policy_controller.h"
#include "hlt/control/stochastic_hybrid.h"
#include "hlt/util/error.h"
#include "support/gradient_check.h"

namespace hlt {
namespace {

struct Models {
  DynamicsModel dynamics{nullptr};
  RewardModel reward{nullptr};
  GaussianPolicy policy{nullptr};
};

// Small random sine models in double precision, with weights large enough that every Jacobian matters.
Models random_models(int n, int m, uint64_t seed, double policy_log_std = 0.0) {
  torch::manual_seed(seed);
  Models md;
  md.dynamics = DynamicsModel(DynamicsModelOptions{n, m, 16, Activation::kSin});
  md.reward = RewardModel(RewardModelOptions{n, m, 16});
  md.policy = GaussianPolicy(GaussianPolicyOptions{n, m, {16}, Activation::kSin});
  md.dynamics->to(torch::kFloat64);
  md.reward->to(torch::kFloat64);
  md.policy->to(torch::kFloat64);
  torch::NoGradGuard g;
  md.dynamics->fc2->weight.mul_(0.5);
  // Give the policy mean a real slope (its output layer starts at +-3e-3) and a chosen constant std.
  auto last_mean = md.policy->mean_layers[1]->as<torch::nn::Linear>();
  last_mean->weight.uniform_(-0.5, 0.5);
  auto last_std = md.policy->log_std_layers[1]->as<torch::nn::Linear>();
  last_std->weight.zero_();
  last_std->bias.fill_(policy_log_std);
  return md;
}

// The models' rollout of the planner's samples V [H, K, m] from s0 [n]: the predicted reward-to-go
// J_t^k [H, K] and the last predicted states s_H [K, n]. `after_step` (if given) maps each predicted state
// before the next step, as the planner's options may.
std::pair<torch::Tensor, torch::Tensor> reward_to_go(
    Models md, const torch::Tensor& s0, const torch::Tensor& V,
    const std::function<torch::Tensor(const torch::Tensor&)>& after_step = nullptr) {
  torch::NoGradGuard g;
  auto s = s0.unsqueeze(0).expand({V.size(1), s0.size(0)});
  std::vector<torch::Tensor> r;
  // A reward model of the next state scores the state each step reaches (after `after_step`).
  const bool next_state_reward = md.reward->options().reads_next_state;
  for (int64_t t = 0; t < V.size(0); ++t) {
    if (!next_state_reward) r.push_back(md.reward->forward(s, V[t]).squeeze(-1));
    s = md.dynamics->forward(s, V[t]);
    if (after_step) s = after_step(s);
    if (next_state_reward) r.push_back(md.reward->forward(s, V[t]).squeeze(-1));
  }
  return {torch::stack(r).flip(0).cumsum(0).flip(0), s};
}

// Predicted reward-to-go from step t with s_t = s and closed-loop actions mu(s) afterwards; optionally the
// first action is given.
double reward_to_go(Models& md, torch::Tensor s, int steps, const torch::Tensor* first_action = nullptr) {
  torch::NoGradGuard g;
  double total = 0;
  s = s.view({1, -1});
  for (int t = 0; t < steps; ++t) {
    torch::Tensor a = (t == 0 && first_action) ? first_action->view({1, -1}) : md.policy->mean_action(s);
    total += md.reward->forward(s, a).item<double>();
    s = md.dynamics->forward(s, a);
  }
  return total;
}

TEST(ModelJacobians, MatchAnalyticJacobianOfSineNetwork) {
  Models md = random_models(4, 2, 11);
  const int H = 3;
  auto X = torch::randn({H, 4}, torch::kFloat64), A = torch::rand({H, 2}, torch::kFloat64) * 2 - 1;
  ModelJacobians J = model_jacobians(md.dynamics, md.reward, md.policy, X, A);
  auto W1 = md.dynamics->fc1->weight, b1 = md.dynamics->fc1->bias, W2 = md.dynamics->fc2->weight;
  for (int t = 0; t < H; ++t) {
    auto pre = torch::mv(W1, torch::cat({X[t], A[t]})) + b1;
    // d f / d [s, a] = [I, 0] + W2 diag(cos(pre)) W1
    auto full = torch::mm(W2 * torch::cos(pre).unsqueeze(0), W1);
    full.narrow(1, 0, 4).add_(torch::eye(4, torch::kFloat64));
    for (int i = 0; i < 4; ++i) {
      for (int j = 0; j < 4; ++j)
        EXPECT_NEAR(J.fs(t * 4 + i, j), full[i][j].item<double>(), 1e-12);
      for (int j = 0; j < 2; ++j)
        EXPECT_NEAR(J.fa(t * 4 + i, j), full[i][4 + j].item<double>(), 1e-12);
    }
    // d mu / d s against finite differences.
    auto fd = testing::finite_difference_gradient(
        [&](const torch::Tensor& s) {
          return md.policy->mean_action(s.view({1, -1}))[0][1];
        },
        X[t]);
    for (int j = 0; j < 4; ++j)
      EXPECT_NEAR(J.mus(t * 2 + 1, j), fd[j].item<double>(), 1e-8);
  }
}

TEST(DeterministicHybrid, AdjointIsGradientOfRewardToGo) {
  for (uint64_t seed : {1, 2, 3}) {
    const int n = 3, m = 2, H = 5;
    Models md = random_models(n, m, seed);
    DeterministicHybrid ctrl(md.policy, md.dynamics, md.reward,
                             DeterministicHybridOptions{H, false, 0.999, false});
    auto s0 = torch::randn({n}, torch::kFloat64);
    const AdjointTrace& tr = ctrl.analyse(s0);
    for (int t = 0; t <= H; ++t) {
      auto st = torch::from_blob(Eigen::VectorXd(tr.states.row(t).transpose()).data(), {n}, torch::kFloat64)
                    .clone();
      auto fd = testing::finite_difference_gradient(
          [&](const torch::Tensor& s) { return torch::tensor(reward_to_go(md, s, H - t), torch::kFloat64); },
          st);
      auto rho =
          torch::from_blob(Eigen::VectorXd(tr.rho.row(t).transpose()).data(), {n}, torch::kFloat64).clone();
      if (t == H) {
        EXPECT_EQ(rho.abs().max().item<double>(), 0.0);
      } else {
        EXPECT_LT(testing::relative_error(rho, fd), 1e-3) << "seed " << seed << " t " << t << "\n"
                                                          << rho << fd;
      }
    }
    // d(return)/d(a_0) = dr/da|_0 + B_0^T rho_1.
    auto a0 =
        torch::from_blob(Eigen::VectorXd(tr.actions.row(0).transpose()).data(), {m}, torch::kFloat64).clone();
    auto fd_a = testing::finite_difference_gradient(
        [&](const torch::Tensor& a) { return torch::tensor(reward_to_go(md, s0, H, &a), torch::kFloat64); },
        a0);
    auto analytic = torch::from_blob(Eigen::VectorXd(tr.dreturn_da0).data(), {m}, torch::kFloat64).clone();
    EXPECT_LT(testing::relative_error(analytic, fd_a), 1e-3) << analytic << fd_a;
  }
}

TEST(DeterministicHybrid, ModeInsertionGradientMatchesFirstOrderFormAndIsNonNegative) {
  for (uint64_t seed : {4, 5, 6, 7}) {
    const int n = 4, m = 2;
    // Small policy variance: log-std -4 -> Sigma = e^-8.
    Models md = random_models(n, m, seed, -4.0);
    DeterministicHybrid ctrl(md.policy, md.dynamics, md.reward,
                             DeterministicHybridOptions{5, false, 0.999, false});
    ctrl.act(torch::randn({n}, torch::kFloat64));
    const AdjointTrace& tr = ctrl.trace();
    const double first_order = tr.dreturn_da0.dot(tr.sigma.cwiseProduct(tr.dreturn_da0));
    const double mig = ctrl.diagnostics().mode_insertion_gradient;
    EXPECT_GE(first_order, 0.0);
    EXPECT_GT(mig, 0.0);
    EXPECT_NEAR(mig, first_order, 1e-2 * first_order) << "seed " << seed;
    // Theorem 1: the action is mu + Sigma * d(return)/da.
    for (int j = 0; j < m; ++j) {
      EXPECT_NEAR(tr.action[j], tr.mean_action[j] + std::exp(-8.0) * tr.dreturn_da0[j], 1e-12);
    }
  }
}

TEST(DeterministicHybrid, WithoutPolicyIsGradientStepFromZero) {
  const int n = 3, m = 1;
  Models md = random_models(n, m, 9);
  DeterministicHybrid ctrl(nullptr, md.dynamics, md.reward,
                           DeterministicHybridOptions{4, false, 0.999, false});
  auto s0 = torch::randn({n}, torch::kFloat64);
  const AdjointTrace& tr = ctrl.analyse(s0);
  EXPECT_EQ(tr.actions.norm(), 0.0);
  // mu = 0, Sigma = I: a* = d(return)/d(a_0) along the zero-action rollout.
  torch::NoGradGuard g;
  auto a0 = torch::zeros({m}, torch::kFloat64);
  auto rollout = [&](const torch::Tensor& a) {
    double total = 0;
    auto s = s0.view({1, -1});
    for (int t = 0; t < 4; ++t) {
      auto at = t == 0 ? a.view({1, -1}) : torch::zeros({1, m}, torch::kFloat64);
      total += md.reward->forward(s, at).item<double>();
      s = md.dynamics->forward(s, at);
    }
    return torch::tensor(total, torch::kFloat64);
  };
  auto fd = testing::finite_difference_gradient(rollout, a0);
  EXPECT_NEAR(tr.action[0], fd[0].item<double>(), 1e-6);
}

TEST(DeterministicHybrid, ExplorationDecaysAndSeedIsDeterministic) {
  Models md = random_models(3, 1, 12);
  auto run = [&](uint64_t seed, int64_t interactions) {
    torch::manual_seed(seed);
    DeterministicHybrid ctrl(md.policy, md.dynamics, md.reward, DeterministicHybridOptions{});
    ctrl.set_interactions(interactions);
    return ctrl.act(torch::ones({3}, torch::kFloat64))[0].item<double>();
  };
  EXPECT_EQ(run(5, 0), run(5, 0));
  // After 20000 interactions the noise std is 0.999^20000 ~ 2e-9: the action is a* itself.
  DeterministicHybrid quiet(md.policy, md.dynamics, md.reward,
                            DeterministicHybridOptions{5, false, 0.999, false});
  const double a_star = quiet.act(torch::ones({3}, torch::kFloat64))[0].item<double>();
  EXPECT_NEAR(run(6, 20000), a_star, 1e-7);
  EXPECT_GT(std::abs(run(6, 0) - a_star), 1e-4);
}

// Where the models predict no gain (a reward that is constant, so rho = 0), the squashed rule acts exactly
// as the policy, tanh(mu_raw), and the bounded rule acts clip(mu_raw), which differs from it.
TEST(DeterministicHybrid, SquashedRuleWithoutCorrectionIsThePolicy) {
  const int n = 3, m = 2;
  Models md = random_models(n, m, 16, 0.3);
  {
    torch::NoGradGuard g;
    md.reward->fc3->weight.zero_();
    // A pre-tanh mean near 0.8, where clip(mu_raw) and tanh(mu_raw) differ by about 0.14.
    md.policy->mean_layers[1]->as<torch::nn::Linear>()->bias.fill_(0.8);
  }
  auto s0 = torch::randn({n}, torch::kFloat64);
  const auto policy_action = md.policy->mean_action(s0.unsqueeze(0)).squeeze(0).detach();
  DeterministicHybridOptions o{5, false, 0.999, false};
  o.rule = DeterministicActionRule::kBoundedSquashed;
  DeterministicHybrid squashed(md.policy, md.dynamics, md.reward, o);
  const auto a_squashed = squashed.act(s0);
  o.rule = DeterministicActionRule::kBounded;
  DeterministicHybrid bounded(md.policy, md.dynamics, md.reward, o);
  const auto a_bounded = bounded.act(s0);
  ASSERT_EQ(squashed.trace().rho.cwiseAbs().maxCoeff(), 0.0);
  for (int j = 0; j < m; ++j) {
    EXPECT_NEAR(a_squashed[j].item<double>(), policy_action[j].item<double>(), 1e-12);
    EXPECT_NEAR(a_bounded[j].item<double>(), std::clamp(bounded.trace().mean_raw[j], -1.0, 1.0), 1e-12);
  }
  EXPECT_GT((a_bounded - a_squashed).abs().max().item<double>(), 0.05);
}

// The bounded rule against a hand computation: a* = mu_raw + Sigma (1 - tanh^2(mu_raw)) B_0^T clamp(rho_0,
// -1, 1), with B_0 = df/da at (s0, mu(s0)) by finite differences and rho_0 the (separately tested) exact
// adjoint.
TEST(DeterministicHybrid, BoundedRuleMatchesHandComputationAndRespectsClamps) {
  for (uint64_t seed : {13, 14, 15}) {
    const int n = 3, m = 2;
    Models md = random_models(n, m, seed, 0.3);
    {
      // A steep reward so that the adjoint leaves [-1, 1] and the clamps matter.
      torch::NoGradGuard g;
      md.reward->fc3->weight.mul_(50.0);
    }
    DeterministicHybridOptions o{5, false, 0.999, false};
    o.rule = DeterministicActionRule::kBounded;
    DeterministicHybrid ctrl(md.policy, md.dynamics, md.reward, o);
    auto s0 = torch::randn({n}, torch::kFloat64);
    const auto executed = ctrl.act(s0);
    const AdjointTrace& tr = ctrl.trace();
    ASSERT_GT(tr.rho.row(0).cwiseAbs().maxCoeff(), 1.0) << "the test needs an adjoint outside [-1, 1]";
    // mu_raw is the policy's pre-tanh mean.
    const auto [mean, log_std] = md.policy->forward(s0.unsqueeze(0));
    for (int j = 0; j < m; ++j) {
      EXPECT_NEAR(tr.mean_raw[j], mean[0][j].item<double>(), 1e-12);
      EXPECT_NEAR(tr.mean_action[j], std::tanh(tr.mean_raw[j]), 1e-12);
      EXPECT_NEAR(tr.sigma[j], std::exp(2 * log_std[0][j].item<double>()), 1e-12);
    }
    auto mu = md.policy->mean_action(s0.unsqueeze(0)).squeeze(0).detach();
    for (int j = 0; j < m; ++j) {
      // B_0^T clamp(rho_0) in direction j: d/da_j of clamp(rho_0)^T f(s0, a).
      Eigen::VectorXd rho0 = tr.rho.row(0).transpose().cwiseMax(-1.0).cwiseMin(1.0);
      auto rho_t = torch::from_blob(rho0.data(), {n}, torch::kFloat64).clone();
      auto fd = testing::finite_difference_gradient(
          [&](const torch::Tensor& a) {
            return (md.dynamics->forward(s0.view({1, -1}), a.view({1, -1})).squeeze(0) * rho_t).sum();
          },
          mu);
      const double dtanh = 1.0 - std::pow(std::tanh(tr.mean_raw[j]), 2);
      const double expected = tr.mean_raw[j] + tr.sigma[j] * dtanh * fd[j].item<double>();
      EXPECT_NEAR(tr.action[j], expected, 1e-6) << "seed " << seed << " dim " << j;
      // The executed action (no exploration) is a* clipped to [-1, 1].
      EXPECT_NEAR(executed[j].item<double>(), std::clamp(expected, -1.0, 1.0), 1e-6);
      EXPECT_LE(std::abs(executed[j].item<double>()), 1.0);
    }
    // The clamp bounds the correction: |a* - mu_raw| <= Sigma (1 - tanh^2) sum_i |B_0[i, j]|.
    Eigen::VectorXd x0 = tr.states.row(0).transpose();
    const ModelJacobians J = model_jacobians(md.dynamics, md.reward, md.policy,
                                             torch::from_blob(x0.data(), {1, n}, torch::kFloat64).clone(),
                                             mu.detach().view({1, m}).clone());
    for (int j = 0; j < m; ++j) {
      const double bound =
          tr.sigma[j] * (1.0 - std::pow(std::tanh(tr.mean_raw[j]), 2)) * J.fa.col(j).cwiseAbs().sum();
      EXPECT_LE(std::abs(tr.action[j] - tr.mean_raw[j]), bound + 1e-9);
    }
    // The exact rule on the same models moves much further: the bound is what the clamp buys.
    DeterministicHybrid exact(md.policy, md.dynamics, md.reward,
                              DeterministicHybridOptions{5, false, 0.999, false});
    exact.analyse(s0);
    EXPECT_GT((exact.trace().action - exact.trace().mean_action).cwiseAbs().maxCoeff(),
              (tr.action - tr.mean_raw).cwiseAbs().maxCoeff());
    // The mode insertion gradient is still reported against the policy's action tanh(mu_raw).
    EXPECT_TRUE(std::isfinite(ctrl.diagnostics().mode_insertion_gradient));
    // The squashed rule takes the same step and maps it through tanh.
    o.rule = DeterministicActionRule::kBoundedSquashed;
    DeterministicHybrid squashed(md.policy, md.dynamics, md.reward, o);
    const auto executed_squashed = squashed.act(s0);
    for (int j = 0; j < m; ++j) {
      EXPECT_NEAR(squashed.trace().action[j], std::tanh(tr.action[j]), 1e-12);
      EXPECT_NEAR(executed_squashed[j].item<double>(), std::tanh(tr.action[j]), 1e-6);
    }
  }
}

// With exploration from the policy, a training action is the rule applied to a draw u ~ N(mu_raw, Sigma) in
// place of mu_raw: under the squashed rule atanh(a) - correction - mu_raw, under the bounded rule a -
// correction - mu_raw, and under the exact rule atanh(a - correction) - mu_raw are the policy's own noise,
// mean 0 and standard deviation Sigma^(1/2) (0.15 here, so nothing is clipped), independent across steps.
TEST(DeterministicHybrid, PolicyExplorationDrawsThePolicysGaussianInsideTheRule) {
  const int n = 3, m = 1;
  Models md = random_models(n, m, 17, std::log(0.15));
  {
    // mu_raw = 0.05 everywhere, far enough from the clip at +-1 for 4 standard deviations of noise.
    torch::NoGradGuard g;
    auto last_mean = md.policy->mean_layers[1]->as<torch::nn::Linear>();
    last_mean->weight.zero_();
    last_mean->bias.fill_(0.05);
  }
  auto s0 = torch::randn({n}, torch::kFloat64);
  for (auto rule : {DeterministicActionRule::kBoundedSquashed, DeterministicActionRule::kBounded,
                    DeterministicActionRule::kExact}) {
    DeterministicHybridOptions o{5, false, 0.999, true};
    o.rule = rule;
    o.exploration = DeterministicExploration::kPolicy;
    DeterministicHybrid ctrl(md.policy, md.dynamics, md.reward, o);
    // The decay schedule would be silent by now; the policy's noise is not.
    ctrl.set_interactions(100000);
    torch::manual_seed(3);
    const int draws = 4000;
    double sum = 0, sum_sq = 0, lag = 0, previous = 0;
    for (int i = 0; i < draws; ++i) {
      const double a = ctrl.act(s0)[0].item<double>();
      const AdjointTrace& tr = ctrl.trace();
      ASSERT_LT(std::abs(tr.mean_raw[0] + tr.correction[0]), 0.3) << "the test needs an unsaturated a*";
      double noise = 0;
      if (rule == DeterministicActionRule::kBoundedSquashed)
        noise = std::atanh(a) - tr.correction[0] - tr.mean_raw[0];
      else if (rule == DeterministicActionRule::kBounded)
        noise = a - tr.correction[0] - tr.mean_raw[0];
      else
        noise = std::atanh(a - tr.correction[0]) - tr.mean_raw[0];
      sum += noise;
      sum_sq += noise * noise;
      lag += noise * previous;
      previous = noise;
    }
    const double mean = sum / draws, sd = std::sqrt(sum_sq / draws - mean * mean);
    // Standard errors: 0.15 / sqrt(4000) = 0.0024 for the mean, about 0.0017 for the std, 0.00036 for the
    // lag-1 product.
    EXPECT_NEAR(mean, 0.0, 0.01) << static_cast<int>(rule);
    EXPECT_NEAR(sd, 0.15, 0.0075) << static_cast<int>(rule);
    EXPECT_NEAR(lag / draws, 0.0, 0.0015) << static_cast<int>(rule);
    // Evaluation (explore off) executes a* itself.
    o.explore = false;
    DeterministicHybrid quiet(md.policy, md.dynamics, md.reward, o);
    const double a_quiet = quiet.act(s0)[0].item<double>();
    EXPECT_NEAR(a_quiet, std::clamp(quiet.trace().action[0], -1.0, 1.0), 1e-12);
  }
}

// One state, one action: s' = s (the model cannot move), r(s, a) = -|s + a - goal|. The best action at every
// step is goal - s, so the optimal plan is constant and known.
Models known_answer_models(double goal) {
  Models md;
  md.dynamics = DynamicsModel(DynamicsModelOptions{1, 1, 2, Activation::kRelu});
  md.reward = RewardModel(RewardModelOptions{1, 1, 2});
  torch::NoGradGuard g;
  for (auto& p : md.dynamics->parameters())
    p.zero_();
  md.reward->fc1->weight.copy_(torch::tensor({{1.0, 1.0}, {-1.0, -1.0}}));
  md.reward->fc1->bias.copy_(torch::tensor({-goal, goal}));
  md.reward->fc2->weight.copy_(torch::eye(2));
  md.reward->fc2->bias.zero_();
  md.reward->fc3->weight.copy_(torch::tensor({{-1.0, -1.0}}));
  md.reward->fc3->bias.zero_();
  return md;
}

TEST(StochasticHybrid, MppiConvergesToKnownOptimum) {
  torch::manual_seed(0);
  Models md = known_answer_models(0.5);
  // White noise (filter 0): with low-pass-filtered noise the reward-to-go weights of step 0 also reward
  // noise that helps the later, less-converged plan entries, which biases a_0 (a property of MPPI's
  // correlated sampling, not of the weights), so the fixed point is only near the optimum.
  StochasticHybrid mppi(std::make_shared<FilteredNoiseSampler>(0.3, 0.0), md.dynamics, md.reward,
                        StochasticHybridOptions{5, 256, 0.01, true, 1e-5}, nullptr, "mppi");
  const auto s0 = torch::tensor({-0.2f});
  // Sampling noise makes single actions scatter; their mean over the converged calls is the optimum.
  double sum = 0;
  for (int i = 0; i < 150; ++i) {
    const double a = mppi.act(s0)[0].item<double>();
    if (i >= 50) sum += a;
  }
  EXPECT_NEAR(sum / 100, 0.7, 0.04);  // goal - s = 0.5 - (-0.2)
}

TEST(StochasticHybrid, PolicySamplerFindsKnownOptimum) {
  torch::manual_seed(1);
  Models md = known_answer_models(-0.3);
  // A broad policy centred at 0 (std e^0.5): the model must pull the plan to goal - s = -0.6.
  auto policy = GaussianPolicy(GaussianPolicyOptions{1, 1, {8}, Activation::kSin});
  {
    torch::NoGradGuard g;
    policy->log_std_layers[1]->as<torch::nn::Linear>()->weight.zero_();
    policy->log_std_layers[1]->as<torch::nn::Linear>()->bias.fill_(0.5);
  }
  // Horizon 1: with longer horizons the later steps' random actions add noise to every sample's
  // reward-to-go, and a single call (the policy sampler ignores the warm start) would be noisy.
  StochasticHybrid hybrid(std::make_shared<PolicySampler>(policy), md.dynamics, md.reward,
                          StochasticHybridOptions{1, 400, 0.01, true, 1e-5}, policy);
  const double a = hybrid.act(torch::tensor({0.3f}))[0].item<double>();
  EXPECT_NEAR(a, -0.6, 0.05);
}

TEST(StochasticHybrid, MeanRolloutFollowsThePolicyMeanAndLeavesTheOtherDraws) {
  Models md = random_models(3, 2, 23);
  const auto s0 = torch::randn({3}, torch::kFloat64);
  auto samples = [&](bool mean_rollout) {
    torch::manual_seed(5);
    StochasticHybrid h(std::make_shared<PolicySampler>(md.policy, false, mean_rollout), md.dynamics,
                       md.reward, StochasticHybridOptions{4, 6, 0.5, true, 1e-5}, md.policy);
    h.act(s0);
    return h.samples().clone();  // [H, K, m]
  };
  const auto with = samples(true), without = samples(false);
  // Rollouts 1..K-1 are the same draws with and without the mean rollout.
  EXPECT_TRUE(torch::equal(with.narrow(1, 1, 5), without.narrow(1, 1, 5)));
  EXPECT_FALSE(torch::equal(with.select(1, 0), without.select(1, 0)));
  // Rollout 0 is the closed loop s_{t+1} = f(s_t, tanh(mu(s_t))) of the learned dynamics.
  torch::NoGradGuard g;
  auto s = s0.unsqueeze(0);
  for (int64_t t = 0; t < 4; ++t) {
    const auto a = md.policy->mean_action(s);
    EXPECT_TRUE(torch::allclose(with[t][0], a[0], 1e-9, 1e-12)) << "step " << t;
    s = md.dynamics->forward(s, a);
  }
}

TEST(StochasticHybrid, WeightsAreFiniteNormalisedAndFollowTheFormula) {
  torch::manual_seed(2);
  Models md = random_models(3, 2, 21);
  const double lambda = 0.5;
  StochasticHybrid hybrid(std::make_shared<PolicySampler>(md.policy), md.dynamics, md.reward,
                          StochasticHybridOptions{6, 30, lambda, true, 0.0}, md.policy);
  const auto s0 = torch::randn({3}, torch::kFloat64);
  hybrid.act(s0);
  const auto w = hybrid.weights().clone();
  ASSERT_EQ(w.sizes(), (std::vector<int64_t>{6, 30}));
  EXPECT_TRUE(torch::isfinite(w).all().item<bool>());
  EXPECT_TRUE(torch::allclose(w.sum(1), torch::ones({6}, torch::kFloat64)));
  // Recompute the weights from the stored samples: w_t^k proportional to exp(J_t^k / lambda) p(v_t^k), with
  // J_t^k the predicted reward-to-go along sample k's rollout.
  torch::NoGradGuard g;
  {
    auto V = hybrid.samples();  // [H, K, m]
    auto J = reward_to_go(md, s0, V).first;
    auto expected = torch::softmax(J / lambda + hybrid.log_density(), 1);
    EXPECT_TRUE(torch::allclose(w, expected, 1e-9, 1e-12));
    // The log-density is the policy's, with the tanh correction.
    auto lp = md.policy->log_prob(s0.unsqueeze(0).expand({30, 3}), V[0]).squeeze(-1);
    EXPECT_TRUE(torch::allclose(hybrid.log_density()[0], lp, 1e-6, 1e-6));
  }
  // Extreme rewards do not overflow: scale the reward model up by 1e6.
  md.reward->fc3->weight.mul_(1e6);
  hybrid.act(torch::randn({3}, torch::kFloat64));
  EXPECT_TRUE(torch::isfinite(hybrid.weights()).all().item<bool>());
  EXPECT_TRUE(torch::allclose(hybrid.weights().sum(1), torch::ones({6}, torch::kFloat64)));
}

// With clamp_to_domain every predicted state is clamped into the dynamics model's domain before the next
// step: the weights equal the formula's along clamped rollouts (and differ from unclamped ones).
// One plan (H 6, K 30, lambda 0.5, the domain clamp on) of a stochastic hybrid on `md` from a random s0, with
// the dynamics model's domain a box around s0 tighter than the rollouts, so that the clamp binds.
struct ClampedPlan {
  torch::Tensor s0, low, high, weights, samples, log_density;
  double lambda = 0.5;
};

ClampedPlan plan_in_a_tight_domain(Models& md) {
  ClampedPlan p;
  StochasticHybridOptions o{6, 30, p.lambda, true, 0.0};
  o.clamp_to_domain = true;
  StochasticHybrid hybrid(std::make_shared<PolicySampler>(md.policy), md.dynamics, md.reward, o, md.policy);
  p.s0 = torch::randn({3}, torch::kFloat64);
  // Before the model has a domain nothing is clamped; a domain tighter than the rollouts then binds.
  EXPECT_FALSE(md.dynamics->has_domain());
  p.low = p.s0 - torch::tensor({0.05, 0.5, 0.0}, torch::kFloat64);
  p.high = p.s0 + torch::tensor({0.05, 0.0, 0.5}, torch::kFloat64);
  md.dynamics->set_domain(p.low, p.high);
  hybrid.act(p.s0);
  p.weights = hybrid.weights().clone();
  p.samples = hybrid.samples().clone();
  p.log_density = hybrid.log_density().clone();
  return p;
}

TEST(StochasticHybrid, ClampToDomainKeepsThePredictedStatesInTheModelsDomain) {
  torch::manual_seed(4);
  Models md = random_models(3, 2, 23);
  const ClampedPlan p = plan_in_a_tight_domain(md);
  torch::NoGradGuard g;
  auto weights_along = [&](bool clamp) {
    int clamped = 0;
    auto clamp_step = [&](const torch::Tensor& s) {
      const auto c = torch::max(torch::min(s, p.high), p.low);
      clamped += (c != s).sum().item<int>();
      return c;
    };
    auto J =
        clamp ? reward_to_go(md, p.s0, p.samples, clamp_step).first : reward_to_go(md, p.s0, p.samples).first;
    if (clamp) {
      EXPECT_GT(clamped, 30);  // the domain binds on many samples and steps
    }
    return torch::softmax(J / p.lambda + p.log_density, 1);
  };
  EXPECT_TRUE(torch::allclose(p.weights, weights_along(true), 1e-9, 1e-12));
  EXPECT_FALSE(torch::allclose(p.weights, weights_along(false), 1e-6, 1e-9));
}

// A reward model of the next state (model.reward_input next_state) scores each step by the state it
// reaches, after the domain clamp: the weights follow the formula with r(s_{t+1}, a_t), not r(s_t, a_t).
// The deterministic hybrid, whose adjoint differentiates r(s_t, a_t), refuses such a model.
TEST(StochasticHybrid, ARewardModelOfTheNextStateScoresTheStatesTheStepsReach) {
  torch::manual_seed(4);
  Models md = random_models(3, 2, 29);
  RewardModelOptions ro{3, 2, 16};
  ro.reads_next_state = true;
  md.reward = RewardModel(ro);
  md.reward->to(torch::kFloat64);
  const ClampedPlan p = plan_in_a_tight_domain(md);
  torch::NoGradGuard g;
  auto clamp_step = [&](const torch::Tensor& s) { return torch::max(torch::min(s, p.high), p.low); };
  const auto J = reward_to_go(md, p.s0, p.samples, clamp_step).first;
  EXPECT_TRUE(torch::allclose(p.weights, torch::softmax(J / p.lambda + p.log_density, 1), 1e-9, 1e-12));
  // The same network read as r(s_t, a_t) weighs the samples otherwise.
  Models as_state = md;
  RewardModelOptions state_options = ro;
  state_options.reads_next_state = false;
  as_state.reward = RewardModel(state_options);
  as_state.reward->to(torch::kFloat64);
  for (const auto& q : md.reward->named_parameters())
    as_state.reward->named_parameters()[q.key()].copy_(q.value());
  const auto J_state = reward_to_go(as_state, p.s0, p.samples, clamp_step).first;
  EXPECT_FALSE(torch::allclose(p.weights, torch::softmax(J_state / p.lambda + p.log_density, 1), 1e-6, 1e-9));
  EXPECT_THROW(DeterministicHybrid(md.policy, md.dynamics, md.reward, DeterministicHybridOptions{}), Error);
}

// With a terminal value every sample's return at every step also counts weight * V(s_H), its last predicted
// state's value: the weights equal the formula's with that tail (and differ from the paper's without it).
TEST(StochasticHybrid, TerminalValueAddsTheLastStatesValueToEveryStepsReturn) {
  torch::manual_seed(5);
  Models md = random_models(3, 2, 23);
  const double lambda = 0.5, weight = 2.0;
  StochasticHybridOptions o{4, 25, lambda, true, 0.0};
  o.terminal_value_weight = weight;
  const auto c = torch::tensor({0.7, -1.3, 0.4}, torch::kFloat64);
  int calls = 0;
  TerminalValue value = [&](const at::Tensor& s) {
    ++calls;
    return torch::tanh(s.matmul(c));  // [K]
  };
  StochasticHybrid hybrid(std::make_shared<PolicySampler>(md.policy), md.dynamics, md.reward, o, md.policy,
                          "stochastic_hybrid", value);
  const auto s0 = torch::randn({3}, torch::kFloat64);
  hybrid.act(s0);
  EXPECT_EQ(calls, 1);  // one batched call per planning call, for all K samples
  const auto w = hybrid.weights().clone();
  torch::NoGradGuard g;
  const auto [J, s_H] = reward_to_go(md, s0, hybrid.samples());
  const auto tail = torch::tanh(s_H.matmul(c));
  EXPECT_TRUE(torch::allclose(hybrid.terminal_values(), tail, 1e-12, 1e-12));
  EXPECT_TRUE(torch::allclose(w, torch::softmax((J + weight * tail) / lambda + hybrid.log_density(), 1), 1e-9,
                              1e-12));
  EXPECT_FALSE(torch::allclose(w, torch::softmax(J / lambda + hybrid.log_density(), 1), 1e-6, 1e-9));

  // A weight needs a value function, and must not be negative; a value of the wrong size is refused.
  EXPECT_THROW(StochasticHybrid(std::make_shared<PolicySampler>(md.policy), md.dynamics, md.reward, o),
               Error);
  StochasticHybridOptions negative = o;
  negative.terminal_value_weight = -1;
  EXPECT_THROW(StochasticHybrid(std::make_shared<PolicySampler>(md.policy), md.dynamics, md.reward, negative,
                                md.policy, "stochastic_hybrid", value),
               Error);
  StochasticHybrid wrong(std::make_shared<PolicySampler>(md.policy), md.dynamics, md.reward, o, md.policy,
                         "stochastic_hybrid",
                         [](const at::Tensor&) { return torch::zeros({3}, torch::kFloat64); });
  EXPECT_THROW(wrong.act(s0), Error);
}

TEST(DynamicsModel, DomainIsTheRangeOfTheStatesItWasGiven) {
  DynamicsModel model(DynamicsModelOptions{2, 1, 8});
  EXPECT_FALSE(model->has_domain());
  model->extend_domain(torch::tensor({{1.0, -2.0}, {3.0, 0.5}}));
  model->extend_domain(torch::tensor({{2.0, -4.0}}, torch::kFloat64));  // converted to the model's dtype
  model->extend_domain(torch::empty({0, 2}));                           // nothing to add
  ASSERT_TRUE(model->has_domain());
  EXPECT_TRUE(torch::equal(model->domain_low(), torch::tensor({1.0f, -4.0f})));
  EXPECT_TRUE(torch::equal(model->domain_high(), torch::tensor({3.0f, 0.5f})));
  EXPECT_THROW(model->extend_domain(torch::tensor({{1.0, std::nan("")}})), Error);
  EXPECT_THROW(model->extend_domain(torch::zeros({2, 3})), Error);
  EXPECT_THROW(model->set_domain(torch::tensor({1.0, 0.0}), torch::tensor({0.0, 1.0})), Error);
  EXPECT_THROW(model->set_domain(torch::zeros({3}), torch::ones({3})), Error);
  // A rejected batch leaves the domain as it was.
  EXPECT_TRUE(torch::equal(model->domain_low(), torch::tensor({1.0f, -4.0f})));
}

// Without the tanh correction the weights use the policy's Gaussian N(mu, Sigma) at the pre-tanh sample u.
TEST(StochasticHybrid, GaussianDensityIsThePolicysGaussianAtThePreTanhSample) {
  torch::manual_seed(4);
  Models md = random_models(3, 2, 22, -0.5);
  const double lambda = 0.5;
  StochasticHybrid squashed(std::make_shared<PolicySampler>(md.policy, true), md.dynamics, md.reward,
                            StochasticHybridOptions{3, 40, lambda, true, 0.0}, md.policy);
  StochasticHybrid gaussian(std::make_shared<PolicySampler>(md.policy, false), md.dynamics, md.reward,
                            StochasticHybridOptions{3, 40, lambda, true, 0.0}, md.policy);
  const auto s0 = torch::randn({3}, torch::kFloat64);
  torch::manual_seed(5);
  squashed.act(s0);
  torch::manual_seed(5);
  gaussian.act(s0);
  torch::NoGradGuard g;
  // The same random numbers: the same samples; the densities differ by exactly the tanh term.
  ASSERT_TRUE(torch::allclose(squashed.samples(), gaussian.samples(), 0, 0));
  auto V = gaussian.samples();  // [H, K, m]
  auto tanh_term = (1 + 1e-6 - V.square()).log().sum(-1);
  EXPECT_TRUE(torch::allclose(gaussian.log_density() - tanh_term, squashed.log_density(), 1e-9, 1e-9));
  // Step 0 (all samples at s0): log N(atanh(v); mu(s0), Sigma(s0)).
  const auto [mean, log_std] = md.policy->forward(s0.unsqueeze(0));
  auto u = torch::atanh(V[0]);
  auto expected = (-0.5 * ((u - mean) / log_std.exp()).square() - log_std - 0.5 * std::log(2 * M_PI)).sum(-1);
  EXPECT_TRUE(torch::allclose(gaussian.log_density()[0], expected, 1e-6, 1e-6));
  // The weights follow exp(J / lambda) p(v) with that density.
  auto J = reward_to_go(md, s0, V).first;
  EXPECT_TRUE(torch::allclose(gaussian.weights(), torch::softmax(J / lambda + gaussian.log_density(), 1),
                              1e-9, 1e-12));
  // Diagnostics: the effective sample size is 1 / sum w^2 of step 0, the saturated weight in [0, 1].
  auto w0 = gaussian.weights()[0];
  EXPECT_NEAR(gaussian.diagnostics().weight_ess, 1.0 / w0.square().sum().item<double>(), 1e-9);
  EXPECT_GE(gaussian.diagnostics().weight_ess, 1.0 - 1e-12);
  EXPECT_LE(gaussian.diagnostics().weight_ess, 40.0 + 1e-9);
  auto sat = (V[0].abs() > 0.99).any(-1).to(torch::kFloat64);
  EXPECT_NEAR(gaussian.diagnostics().saturated_weight, (w0 * sat).sum().item<double>(), 1e-12);
}

// The mixture: the first K1 rollouts are the policy sampler's own draws, the rest NN-MPPI's noise around the
// plan; every sample's log-density is the policy's Gaussian at atanh(v) at that sample's rollout state.
TEST(StochasticHybrid, MixtureSamplerSplitsTheRolloutsAndScoresAllByThePolicy) {
  Models md = random_models(3, 1, 23, -0.5);
  const auto s0 = torch::randn({3}, torch::kFloat64);
  torch::manual_seed(8);
  StochasticHybrid alone(std::make_shared<PolicySampler>(md.policy, false), md.dynamics, md.reward,
                         StochasticHybridOptions{4, 12, 0.5, true, 0.0}, md.policy);
  alone.act(s0);
  torch::manual_seed(8);
  auto mixture =
      std::make_shared<MixtureSampler>(std::make_shared<PolicySampler>(md.policy, false),
                                       std::make_shared<FilteredNoiseSampler>(0.3, 0.5), 5, md.policy);
  const double lambda = 0.5;
  StochasticHybrid mixed(mixture, md.dynamics, md.reward, StochasticHybridOptions{4, 17, lambda, true, 0.0},
                         md.policy);
  mixed.act(s0);
  // The same first random draws: the policy part is identical (its rollouts do not depend on the others),
  // and so is its log-density (up to the atanh round trip).
  EXPECT_TRUE(torch::allclose(mixed.samples().narrow(1, 0, 12), alone.samples(), 0, 0));
  EXPECT_TRUE(torch::allclose(mixed.log_density().narrow(1, 0, 12), alone.log_density(), 1e-6, 1e-6));
  // The noise part: step 0 is the (zero) plan plus 0.5 * 0.3 * z, inside [-1, 1].
  auto V = mixed.samples();  // [H, K, m]
  auto noise = V.narrow(1, 12, 5);
  EXPECT_LE(noise.abs().max().item<double>(), 1.0);
  EXPECT_LT(noise[0].abs().max().item<double>(), 0.15 * 6);
  // Every sample's density and weight by hand: roll the models forward, the policy's Gaussian at each state.
  torch::NoGradGuard g;
  auto s = s0.unsqueeze(0).expand({17, 3}).clone();
  std::vector<torch::Tensor> r, lp;
  for (int t = 0; t < 4; ++t) {
    const auto [mean, log_std] = md.policy->forward(s);
    auto u = torch::atanh(V[t].clamp(-1 + 1e-6, 1 - 1e-6));
    lp.push_back((-0.5 * ((u - mean) / log_std.exp()).square() - log_std - 0.5 * std::log(2 * M_PI)).sum(-1));
    r.push_back(md.reward->forward(s, V[t]).squeeze(-1));
    s = md.dynamics->forward(s, V[t]);
  }
  auto log_p = torch::stack(lp);
  EXPECT_TRUE(torch::allclose(mixed.log_density(), log_p, 1e-6, 1e-6)) << mixed.log_density() << log_p;
  auto J = torch::stack(r).flip(0).cumsum(0).flip(0);
  EXPECT_TRUE(torch::allclose(mixed.weights(), torch::softmax(J / lambda + log_p, 1), 1e-6, 1e-9));
  // The first sampler needs at least one rollout.
  StochasticHybrid too_few(mixture, md.dynamics, md.reward, StochasticHybridOptions{4, 5, 0.5, true, 0.0},
                           md.policy);
  EXPECT_THROW(too_few.act(s0), std::exception);
}

// A policy far from the optimum. The policy sampler alone cannot leave it; with samples around the
// warm-started plan and flat weights the planner walks to the known optimum goal - s; with the policy's
// density in the weights (Theorem 2's bound) a confident policy keeps the plan, a broad one lets it go.
GaussianPolicy constant_policy(double mean_raw, double log_std) {
  auto policy = GaussianPolicy(GaussianPolicyOptions{1, 1, {8}, Activation::kSin});
  torch::NoGradGuard g;
  auto mean_last = policy->mean_layers[1]->as<torch::nn::Linear>();
  mean_last->weight.zero_();
  mean_last->bias.fill_(mean_raw);
  policy->log_std_layers[1]->as<torch::nn::Linear>()->weight.zero_();
  policy->log_std_layers[1]->as<torch::nn::Linear>()->bias.fill_(log_std);
  return policy;
}

// With a scale policy the plan samples' noise std is min(sigma, exp(log_std(s))) of the policy: a confident
// policy (std 0.018) narrows it, a broad one (std 1) leaves sigma; the log-density uses each step's std.
TEST(StochasticHybrid, PlanNoiseFromThePolicyIsNoWiderThanThePolicy) {
  const int64_t H = 3, K = 4000;
  const double sigma = 0.3;
  const auto plan = torch::zeros({H, 1}, torch::kFloat32);
  const auto states = torch::zeros({K, 1}, torch::kFloat32);
  auto noise_std = [&](std::optional<GaussianPolicy> scale, double expected_sigma) {
    FilteredNoiseSampler sampler(sigma, 0.0, scale);
    torch::manual_seed(3);
    sampler.begin(K, plan);
    auto a = torch::empty({K, 1}, torch::kFloat32);
    std::vector<torch::Tensor> steps;
    for (int64_t t = 0; t < H; ++t) {
      sampler.sample(t, states, plan[t], a);
      steps.push_back(a.clone());
    }
    const auto V = torch::stack(steps);  // [H, K, 1]; filter 0 and a zero plan: v = clip(sigma_t z)
    // z is known (the same seed): the density of each step's noise under N(0, expected_sigma^2).
    torch::manual_seed(3);
    const auto z = torch::randn({H, K, 1}, torch::kFloat32);
    EXPECT_TRUE(torch::allclose(V, (expected_sigma * z).clamp(-1, 1), 1e-5, 1e-6));
    const auto by_hand = (-0.5 * z.square() - std::log(expected_sigma) - 0.5 * std::log(2 * M_PI)).sum(-1);
    EXPECT_TRUE(torch::allclose(sampler.log_density(V), by_hand, 1e-5, 1e-6));
    return V.std().item<double>();
  };
  EXPECT_NEAR(noise_std(std::nullopt, sigma), sigma, 0.01);
  EXPECT_NEAR(noise_std(constant_policy(-1.0, -4.0), std::exp(-4.0)), std::exp(-4.0), 0.001);
  EXPECT_NEAR(noise_std(constant_policy(-1.0, 0.0), sigma), sigma, 0.01);
}

TEST(StochasticHybrid, PlanSamplesLetTheModelsLeaveAPoorPolicy) {
  torch::manual_seed(9);
  Models md = known_answer_models(0.5);
  const auto s0 = torch::tensor({-0.2f});
  auto average_action = [&](GaussianPolicy policy, int64_t plan_samples, bool density) {
    std::shared_ptr<ActionSampler> sampler = std::make_shared<PolicySampler>(policy, false);
    if (plan_samples > 0) {
      sampler = std::make_shared<MixtureSampler>(sampler, std::make_shared<FilteredNoiseSampler>(0.5, 0.0),
                                                 plan_samples, policy);
    }
    StochasticHybrid h(sampler, md.dynamics, md.reward,
                       StochasticHybridOptions{1, 40 + plan_samples, 0.01, density, 1e-5}, policy);
    double sum = 0;
    for (int i = 0; i < 100; ++i) {
      const double a = h.act(s0)[0].item<double>();
      if (i >= 50) sum += a;
    }
    return sum / 50;
  };
  const auto confident = constant_policy(-1.0, -4.0);                       // tanh(-1) = -0.76, std 0.018
  const auto broad = constant_policy(-1.0, 0.0);                            // std 1 before the tanh
  EXPECT_NEAR(average_action(confident, 0, true), std::tanh(-1.0), 0.05);   // stuck at the policy
  EXPECT_NEAR(average_action(confident, 40, false), 0.7, 0.08);             // goal - s = 0.5 - (-0.2)
  EXPECT_NEAR(average_action(confident, 40, true), std::tanh(-1.0), 0.05);  // the bound holds the plan
  EXPECT_NEAR(average_action(broad, 40, true), 0.7, 0.08);                  // the models decide
}

TEST(StochasticHybrid, UniformWeightsHaveFullEffectiveSampleSize) {
  torch::manual_seed(6);
  Models md = random_models(2, 1, 32);
  StochasticHybrid h(std::make_shared<PolicySampler>(md.policy, false), md.dynamics, md.reward,
                     StochasticHybridOptions{3, 25, 1e12, false, 0.0}, md.policy);
  h.act(torch::randn({2}, torch::kFloat64));
  EXPECT_NEAR(h.diagnostics().weight_ess, 25.0, 1e-9);
}

TEST(StochasticHybrid, ADivergedSampleGetsNoWeightAndTheOthersShareIt) {
  // Sample 2's rollout left the numbers (its return is NaN from step 0, its density Inf at step 1).
  const double nan = std::numeric_limits<double>::quiet_NaN();
  RowMatrix<double> scaled(2, 4), density(2, 4);
  scaled << 0.5, 1.0, nan, 2.0, 0.1, 0.4, nan, 0.3;
  density << -1.0, -0.5, -2.0, -0.2, -0.3, -0.1, std::numeric_limits<double>::infinity(), -0.7;
  // The three finite samples alone.
  RowMatrix<double> s3(2, 3), d3(2, 3);
  s3 << 0.5, 1.0, 2.0, 0.1, 0.4, 0.3;
  d3 << -1.0, -0.5, -0.2, -0.3, -0.1, -0.7;
  for (double min_ess : {0.0, 2.5}) {
    const RowMatrix<double> w = planner_weights<double>(scaled, &density, 0.0, min_ess);
    const RowMatrix<double> w3 = planner_weights<double>(s3, &d3, 0.0, min_ess);
    ASSERT_TRUE(w.allFinite());
    EXPECT_EQ(w(0, 2), 0.0);
    EXPECT_EQ(w(1, 2), 0.0);
    for (int t = 0; t < 2; ++t) {
      EXPECT_EQ(w(t, 0), w3(t, 0));
      EXPECT_EQ(w(t, 1), w3(t, 1));
      EXPECT_EQ(w(t, 3), w3(t, 2));
    }
  }
  // A NaN in the density alone also leaves the sample out.
  density(0, 2) = -2.0;
  density(1, 2) = nan;
  scaled(0, 2) = scaled(1, 2) = 0.0;
  EXPECT_EQ(planner_weights<double>(scaled, &density, 0.0, 0.0)(0, 2), 0.0);
  // No finite sample: NaN weights, which make the controller fall back to its policy.
  scaled.setConstant(nan);
  EXPECT_FALSE(planner_weights<double>(scaled, nullptr, 0.0, 0.0).allFinite());
}

TEST(StochasticHybrid, MinimumEffectiveSampleSizeTempersOnlyTheRowsThatNeedIt) {
  // Row 0: returns far apart (one sample takes all the weight); row 1: equal returns (already uniform).
  RowMatrix<double> scaled(2, 4);
  scaled << 0, 10, 20, 30, 5, 5, 5, 5;
  RowMatrix<double> density(2, 4);
  density << 0, -1, 0, -1, 0, 0, 0, 0;
  auto ess = [](const RowMatrix<double>& w, int t) { return 1.0 / w.row(t).squaredNorm(); };
  Eigen::VectorXd beta;
  const RowMatrix<double> paper = planner_weights<double>(scaled, &density, 0.0, 0.0, &beta);
  EXPECT_LT(ess(paper, 0), 1.001);  // the paper's rule: nearly all weight on the best sample
  EXPECT_EQ(beta(0), 1.0);
  const RowMatrix<double> w = planner_weights<double>(scaled, &density, 0.0, 2.5, &beta);
  EXPECT_NEAR(ess(w, 0), 2.5, 1e-6);  // tempered to the floor, no further
  EXPECT_GT(beta(0), 0.0);
  EXPECT_LT(beta(0), 1.0);
  // The tempered row is the paper's formula at that beta, by hand.
  for (int k = 0; k < 4; ++k) {
    double z = 0;
    for (int j = 0; j < 4; ++j)
      z += std::exp(beta(0) * (scaled(0, j) - scaled(0, k)) + density(0, j) - density(0, k));
    EXPECT_NEAR(w(0, k), 1.0 / z, 1e-9);
  }
  EXPECT_EQ(beta(1), 1.0);  // row 1 already had ESS 4: untouched
  EXPECT_NEAR(ess(w, 1), 4.0, 1e-9);
  EXPECT_TRUE(w.row(1).isApprox(paper.row(1)));

  // In the controller: its step-0 diagnostics reach the floor that the paper's rule falls below.
  torch::manual_seed(6);
  Models md = random_models(2, 1, 32);
  StochasticHybridOptions o{3, 25, 1e-4, false, 0.0};
  StochasticHybrid cold(std::make_shared<PolicySampler>(md.policy, false), md.dynamics, md.reward, o,
                        md.policy);
  const auto s0 = torch::randn({2}, torch::kFloat64);
  torch::manual_seed(7);
  cold.act(s0);
  EXPECT_LT(cold.diagnostics().weight_ess, 2.0);
  o.min_ess = 8;
  StochasticHybrid floored(std::make_shared<PolicySampler>(md.policy, false), md.dynamics, md.reward, o,
                           md.policy);
  torch::manual_seed(7);
  floored.act(s0);
  EXPECT_NEAR(floored.diagnostics().weight_ess, 8.0, 1e-3);
  o.min_ess = 26;  // more than K: refused
  EXPECT_THROW(StochasticHybrid(std::make_shared<PolicySampler>(md.policy, false), md.dynamics, md.reward, o,
                                md.policy),
               Error);
}

TEST(StochasticHybrid, InfiniteTemperatureGivesMeanPerturbationAndPlanShifts) {
  torch::manual_seed(3);
  Models md = random_models(2, 1, 31);
  StochasticHybridOptions o{4, 50, 1e12, false, 1e-5};
  StochasticHybrid mppi(std::make_shared<FilteredNoiseSampler>(0.3, 0.5), md.dynamics, md.reward, o, nullptr,
                        "mppi");
  auto s = torch::randn({2}, torch::kFloat64);
  mppi.act(s);
  const auto plan1 = mppi.plan().clone();
  mppi.act(s);
  // Second call: the plan it started from is plan1 shifted one step earlier with a zero appended.
  auto shifted = torch::cat({plan1.narrow(0, 1, 3), torch::zeros({1, 1}, torch::kFloat64)});
  EXPECT_TRUE(torch::allclose(mppi.weights(), torch::full({4, 50}, 1.0 / 50, torch::kFloat64)));
  auto expected = shifted + (mppi.samples() - shifted.unsqueeze(1)).mean(1);
  EXPECT_TRUE(torch::allclose(mppi.plan(), expected, 1e-12, 1e-12)) << mppi.plan() << expected;
  // With the density in the weights, lambda -> infinity leaves w proportional to p(v).
  StochasticHybrid dens(std::make_shared<FilteredNoiseSampler>(0.3, 0.5), md.dynamics, md.reward,
                        StochasticHybridOptions{4, 50, 1e12, true, 0.0}, nullptr, "mppi");
  dens.act(s);
  EXPECT_TRUE(torch::allclose(dens.weights(), torch::softmax(dens.log_density(), 1), 1e-9, 1e-12));
  // reset() clears the warm start.
  dens.reset();
  EXPECT_EQ(dens.plan().abs().sum().item<double>(), 0.0);
}

TEST(StochasticHybrid, AveragingBeforeTheSquashGivesThePoliciesOwnActionUnderUniformWeights) {
  // A broad policy with a constant mean: mu = 0.8, sigma = e^0.5 = 1.65 in both action dimensions.
  Models md = random_models(2, 2, 41, 0.5);
  {
    torch::NoGradGuard g;
    auto last_mean = md.policy->mean_layers[1]->as<torch::nn::Linear>();
    last_mean->weight.zero_();
    last_mean->bias.fill_(0.8);
  }
  const auto s0 = torch::randn({2}, torch::kFloat64);
  auto run = [&](bool before_squash, double lambda, bool density) {
    torch::manual_seed(7);
    StochasticHybridOptions o{3, 4000, lambda, density, 1e-5};
    o.average_before_squash = before_squash;
    auto h = std::make_unique<StochasticHybrid>(std::make_shared<PolicySampler>(md.policy, false),
                                                md.dynamics, md.reward, o, md.policy);
    h->act(s0);
    return h;
  };
  // Uniform weights (lambda -> infinity, no density): the paper's plan is the mean of the squashed draws,
  // E tanh(0.8 + 1.65 z) = 0.331 (quadrature), far below tanh(0.8) = 0.664; averaged before the squash it is
  // tanh of the draws' mean, within 4 standard errors (1.65 / sqrt(4000) = 0.026, times 1 - 0.664^2) of
  // tanh(0.8).
  const auto paper = run(false, 1e12, false), before = run(true, 1e12, false);
  EXPECT_TRUE(torch::equal(paper->samples(), before->samples()));
  EXPECT_TRUE(torch::allclose(paper->plan(), paper->samples().mean(1), 1e-12, 1e-12));
  const auto u = torch::atanh(before->samples().clamp(-(1 - 1e-6), 1 - 1e-6));
  EXPECT_TRUE(torch::allclose(before->plan(), torch::tanh(u.mean(1)), 1e-12, 1e-12));
  for (int64_t i = 0; i < 2; ++i) {
    EXPECT_NEAR(paper->plan()[0][i].item<double>(), 0.331, 0.03);
    EXPECT_NEAR(before->plan()[0][i].item<double>(), std::tanh(0.8), 4 * 0.026 * (1 - 0.664 * 0.664));
  }
  // With the models' weights (and the density): a_t = tanh(sum_k w_t^k atanh(v_t^k)).
  const auto weighted = run(true, 0.05, true);
  const auto uw = torch::atanh(weighted->samples().clamp(-(1 - 1e-6), 1 - 1e-6));
  EXPECT_TRUE(torch::allclose(weighted->plan(), torch::tanh((weighted->weights().unsqueeze(-1) * uw).sum(1)),
                              1e-12, 1e-12));
  EXPECT_LT(weighted->diagnostics().weight_ess, 3900.0);
}

TEST(StochasticHybrid, SameSeedSameActions) {
  Models md = random_models(3, 1, 41);
  auto run = [&] {
    torch::manual_seed(77);
    StochasticHybrid h(std::make_shared<PolicySampler>(md.policy), md.dynamics, md.reward,
                       StochasticHybridOptions{}, md.policy);
    std::vector<double> out;
    auto s = torch::ones({3}, torch::kFloat64);
    for (int i = 0; i < 5; ++i)
      out.push_back(h.act(s)[0].item<double>());
    return out;
  };
  EXPECT_EQ(run(), run());
}

TEST(Controller, NonFiniteModelFallsBackToPolicyAndCounts) {
  Models md = random_models(3, 1, 51);
  {
    torch::NoGradGuard g;
    md.dynamics->fc2->bias.fill_(std::numeric_limits<double>::quiet_NaN());
  }
  auto s = torch::randn({3}, torch::kFloat64);
  StochasticHybrid stoch(std::make_shared<PolicySampler>(md.policy), md.dynamics, md.reward,
                         StochasticHybridOptions{}, md.policy);
  DeterministicHybrid det(md.policy, md.dynamics, md.reward, DeterministicHybridOptions{});
  const auto policy_action = md.policy->mean_action(s.unsqueeze(0)).squeeze(0).detach();
  for (Controller* c : std::initializer_list<Controller*>{&stoch, &det}) {
    auto a = c->act(s);
    EXPECT_TRUE(torch::isfinite(a).all().item<bool>()) << c->name();
    EXPECT_TRUE(torch::allclose(a, policy_action)) << c->name();
    EXPECT_TRUE(c->diagnostics().fell_back);
    c->act(s);
    EXPECT_EQ(c->diagnostics().fallbacks, 2);
  }
  // No policy to fall back on: the zero action.
  DeterministicHybrid mpc(nullptr, md.dynamics, md.reward, DeterministicHybridOptions{});
  EXPECT_EQ(mpc.act(s).abs().sum().item<double>(), 0.0);
  // A NaN policy falls back to zero too.
  {
    torch::NoGradGuard g;
    for (auto& p : md.policy->parameters())
      p.fill_(std::numeric_limits<double>::quiet_NaN());
  }
  PolicyController pc(md.policy, true);
  EXPECT_EQ(pc.act(s).abs().sum().item<double>(), 0.0);
}

}  // namespace
}  // namespace hlt
