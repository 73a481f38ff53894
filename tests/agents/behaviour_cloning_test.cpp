// Behaviour cloning: its loss against a hand computation of the tanh-Gaussian NLL (with actions at the
// bound as censored observations), and learning known experts from their demonstrations.
#include "agents/behaviour_cloning.h"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>

#include "hlt/util/error.h"

namespace hlt {
namespace {

// A one-dimensional policy with every weight zero: mu = 0.2 (the mean head's last bias), log std = -0.5.
GaussianPolicy constant_policy() {
  GaussianPolicy policy(GaussianPolicyOptions{1, 1, {2}, Activation::kRelu});
  torch::NoGradGuard g;
  for (auto& p : policy->parameters())
    p.zero_();
  policy->mean_layers[1]->as<torch::nn::Linear>()->bias.fill_(0.2);
  policy->log_std_layers[1]->as<torch::nn::Linear>()->bias.fill_(-0.5);
  return policy;
}

TEST(BehaviourCloning, LossIsTheHandComputedNegativeLogLikelihood) {
  torch::manual_seed(0);
  GaussianPolicy policy = constant_policy();
  BehaviourCloning bc(policy, BehaviourCloningOptions{});
  const auto states = torch::zeros({2, 1});
  const auto actions = torch::tensor({{0.5f}, {-0.3f}});
  // -log pi(a) = -[log N(atanh a; 0.2, e^-0.5) - log(1 - a^2 + 1e-6)], averaged over the two actions.
  double expected = 0;
  for (double a : {0.5, -0.3}) {
    const double u = std::atanh(a), sigma = std::exp(-0.5);
    const double log_n = -0.5 * std::pow((u - 0.2) / sigma, 2) - std::log(sigma) - 0.5 * std::log(2 * M_PI);
    expected += -(log_n - std::log(1 - a * a + 1e-6)) / 2;
  }
  EXPECT_NEAR(bc.loss(states, actions), expected, 1e-5);
  EXPECT_NEAR(bc.update(states, actions), expected, 1e-5);
  EXPECT_LT(bc.loss(states, actions), expected);  // the step lowered it
}

double log_normal_cdf(double x) {
  return std::log(0.5 * std::erfc(-x / std::sqrt(2.0)));
}

TEST(BehaviourCloning, ActionsAtTheBoundAreCensoredObservations) {
  const auto states = torch::zeros({3, 1});
  const auto actions = torch::tensor({{0.5f}, {1.0f}, {-1.0f}});
  const double mu = 0.2, sigma = std::exp(-0.5), c = std::atanh(kCensorLevel);
  const double u = std::atanh(0.5);
  const double inside = -0.5 * std::pow((u - mu) / sigma, 2) - std::log(sigma) - 0.5 * std::log(2 * M_PI) -
                        std::log(1 - 0.25 + 1e-6);
  // +1: log P(u >= c) = log Phi((mu - c) / sigma); -1: log P(u <= -c) = log Phi((-c - mu) / sigma).
  const double expected =
      -(inside + log_normal_cdf((mu - c) / sigma) + log_normal_cdf((-c - mu) / sigma)) / 3;
  BehaviourCloning censored(constant_policy(), BehaviourCloningOptions{});
  EXPECT_NEAR(censored.loss(states, actions), expected, 1e-4);

  // Without censoring, +-1 are densities at atanh(+-(1 - 1e-6)), far out in the tail: a much larger loss.
  BehaviourCloningOptions plain;
  plain.censor_saturated = false;
  BehaviourCloning density(constant_policy(), plain);
  double expected_plain = -inside / 3;
  for (double a : {1.0 - 1e-6, -(1.0 - 1e-6)}) {
    const double v = std::atanh(a);
    expected_plain -= (-0.5 * std::pow((v - mu) / sigma, 2) - std::log(sigma) - 0.5 * std::log(2 * M_PI) -
                       std::log(1 - a * a + 1e-6)) /
                      3;
  }
  EXPECT_NEAR(density.loss(states, actions), expected_plain, 1e-2 * std::abs(expected_plain));
  EXPECT_GT(density.loss(states, actions), censored.loss(states, actions) + 10);
}

TEST(BehaviourCloning, ALogStdHeadPastItsBoundIsPulledBack) {
  // The log-std head outputs 3.5, past the bound 2: a plain clamp has no gradient there, so the head would
  // stay put (the state is 0, so only the bias moves it). The loss is the NLL at log std 2; its gradient
  // with respect to the log-std, 1 - z^2 > 0 for these actions, points back into range and gets through.
  for (bool censor : {true, false}) {
    GaussianPolicy policy = constant_policy();
    auto& bias = policy->log_std_layers[1]->as<torch::nn::Linear>()->bias;
    {
      torch::NoGradGuard g;
      bias.fill_(3.5);
    }
    BehaviourCloningOptions options;
    options.censor_saturated = censor;
    BehaviourCloning bc(policy, options);
    const auto states = torch::zeros({2, 1});
    const auto actions = torch::tensor({{0.5f}, {-0.3f}});
    double expected = 0;
    for (double a : {0.5, -0.3}) {
      const double u = std::atanh(a), sigma = std::exp(2.0);
      const double log_n = -0.5 * std::pow((u - 0.2) / sigma, 2) - std::log(sigma) - 0.5 * std::log(2 * M_PI);
      expected += -(log_n - std::log(1 - a * a + 1e-6)) / 2;
    }
    EXPECT_NEAR(bc.loss(states, actions), expected, 1e-5) << "censor " << censor;
    // Adam moves the bias by about lr = 0.01 a step: 300 steps cover the 1.5 past the bound.
    for (int i = 0; i < 300; ++i)
      bc.update(states, actions);
    EXPECT_LT(bias.item<double>(), 2.0) << "censor " << censor;  // back inside, where the NLL pulls it
  }
}

TEST(BehaviourCloning, ALogStdHeadPastItsBoundIsNotPushedInAgainstTheLoss) {
  // Only actions at +1, censored, with the mean below the censoring level: the likelihood P(u >= c) grows
  // with the spread, so the loss wants the head further out. Past the bound that gradient is withheld (a
  // penalty would drag the head in against the data); the mean still learns.
  GaussianPolicy policy = constant_policy();
  auto& log_std_bias = policy->log_std_layers[1]->as<torch::nn::Linear>()->bias;
  auto& mean_bias = policy->mean_layers[1]->as<torch::nn::Linear>()->bias;
  {
    torch::NoGradGuard g;
    log_std_bias.fill_(2.5);
  }
  BehaviourCloning bc(policy, BehaviourCloningOptions{});
  const auto states = torch::zeros({2, 1});
  const auto actions = torch::ones({2, 1});
  const double mu = 0.2, sigma = std::exp(2.0), c = std::atanh(kCensorLevel);
  EXPECT_NEAR(bc.loss(states, actions), -log_normal_cdf((mu - c) / sigma), 1e-5);
  for (int i = 0; i < 20; ++i)
    bc.update(states, actions);
  EXPECT_DOUBLE_EQ(log_std_bias.item<double>(), 2.5);
  EXPECT_GT(mean_bias.item<double>(), 0.3);  // the mean moves towards the saturated actions
}

TEST(BehaviourCloning, LearnsAClippedExpert) {
  // An expert whose first action is clipped at the bound on two thirds of the states: the censored fit
  // acts at the bound where the expert did and learns the unclipped second action.
  torch::manual_seed(2);
  GaussianPolicy policy(GaussianPolicyOptions{1, 2, {32}, Activation::kRelu});
  BehaviourCloning bc(policy, BehaviourCloningOptions{0.01});
  const auto states = torch::rand({512, 1}) * 2 - 1;
  const auto first = (states * 3).clamp(-1, 1);  // |3 s| > 1 on two thirds of the states: clipped
  const auto second = torch::tanh(0.5 * states);
  const auto actions = torch::cat({first, second}, 1);
  for (int i = 0; i < 1500; ++i)
    bc.update(states, actions);
  const auto test = torch::linspace(-1, 1, 41).unsqueeze(1);
  const auto a = policy->mean_action(test);
  EXPECT_LT((a.select(1, 1) - torch::tanh(0.5 * test.squeeze(1))).abs().max().item<double>(), 0.05);
  const auto clipped = (test.squeeze(1) * 3).abs() > 1.2;
  const auto at_bound = (a.select(1, 0) * torch::sign(test.squeeze(1))).masked_select(clipped);
  EXPECT_GT(at_bound.min().item<double>(), 0.95);
}

TEST(BehaviourCloning, LearnsALinearExpertFromItsDemonstrations) {
  torch::manual_seed(1);
  GaussianPolicy policy(GaussianPolicyOptions{3, 2, {32}, Activation::kRelu});
  BehaviourCloning bc(policy, BehaviourCloningOptions{0.01});
  const auto W = torch::tensor({{0.5f, -0.2f}, {0.1f, 0.4f}, {-0.3f, 0.2f}});
  const auto states = torch::rand({512, 3}) * 2 - 1;
  const auto actions = torch::tanh(states.mm(W));
  const double before = bc.loss(states, actions);
  for (int i = 0; i < 800; ++i)
    bc.update(states, actions);
  EXPECT_LT(bc.loss(states, actions), before - 2.0);
  const auto test_states = torch::rand({64, 3}) * 2 - 1;
  const auto error = (policy->mean_action(test_states) - torch::tanh(test_states.mm(W))).abs().max();
  EXPECT_LT(error.item<double>(), 0.05);
}

TEST(BehaviourCloning, WeightDecayMovesOnlyTheWeightMatrices) {
  // At zero states the loss gives the first layer's weights no gradient (dL/dW = delta x^T = 0), so with the
  // decay theirs is wd * W alone: Adam's first step moves each by lr against its sign. Everything else, the
  // biases included, steps exactly as without the decay.
  torch::manual_seed(3);
  GaussianPolicy plain_policy(GaussianPolicyOptions{2, 1, {4}, Activation::kRelu});
  GaussianPolicy decayed_policy(GaussianPolicyOptions{2, 1, {4}, Activation::kRelu});
  {
    torch::NoGradGuard g;
    auto from = plain_policy->parameters();
    auto to = decayed_policy->parameters();
    for (size_t i = 0; i < from.size(); ++i)
      to[i].copy_(from[i]);
  }
  BehaviourCloningOptions decay;
  decay.lr = 0.01;
  decay.weight_decay = 0.1;
  BehaviourCloning plain(plain_policy, BehaviourCloningOptions{0.01});
  BehaviourCloning decayed(decayed_policy, decay);
  const auto states = torch::zeros({4, 2});
  const auto actions = torch::tensor({{0.5f}, {-0.3f}, {0.1f}, {0.2f}});
  const at::Tensor w_before = decayed_policy->mean_layers[0]->as<torch::nn::Linear>()->weight.clone();
  EXPECT_DOUBLE_EQ(plain.update(states, actions), decayed.update(states, actions));  // the loss has no decay
  const at::Tensor w_after = decayed_policy->mean_layers[0]->as<torch::nn::Linear>()->weight;
  EXPECT_TRUE(torch::allclose(w_after, w_before - 0.01 * torch::sign(w_before), 0, 1e-6));
  EXPECT_TRUE(torch::equal(plain_policy->mean_layers[0]->as<torch::nn::Linear>()->weight, w_before));
  for (const auto& p : plain_policy->named_parameters()) {
    const at::Tensor other = decayed_policy->named_parameters()[p.key()];
    if (p.key().find("bias") != std::string::npos) EXPECT_TRUE(torch::equal(p.value(), other)) << p.key();
  }
  BehaviourCloningOptions negative;
  negative.weight_decay = -1;
  EXPECT_THROW(BehaviourCloning(plain_policy, negative), Error);
}

TEST(BehaviourCloning, InputNoiseIsScaledByTheBatchSpreadOfEachComponent) {
  // The step's loss is the NLL at states + sigma * std(states) * N(0, 1), with the generator's draw.
  torch::manual_seed(4);
  const auto states = torch::cat({torch::rand({16, 1}) * 10, torch::rand({16, 1}) * 0.01}, 1);
  const auto actions = torch::tanh(states.select(1, 0).unsqueeze(1) * 0.1);
  GaussianPolicy policy(GaussianPolicyOptions{2, 1, {8}, Activation::kRelu});
  BehaviourCloningOptions o;
  o.input_noise = 0.3;
  BehaviourCloning bc(policy, o);
  torch::manual_seed(5);
  const auto noise = torch::randn_like(states);
  const double expected = bc.loss(states + 0.3 * states.std(0, true, true) * noise, actions);
  EXPECT_GT(std::abs(expected - bc.loss(states, actions)), 1e-4);  // the noise changes the loss
  torch::manual_seed(5);
  EXPECT_NEAR(bc.update(states, actions), expected, 1e-6);
}

}  // namespace
}  // namespace hlt
