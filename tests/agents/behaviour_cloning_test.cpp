// Behaviour cloning: its loss against a hand computation of the tanh-Gaussian NLL, and learning a known
// expert from its demonstrations.
#include "agents/behaviour_cloning.h"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>

namespace hlt {
namespace {

TEST(BehaviourCloning, LossIsTheHandComputedNegativeLogLikelihood) {
  torch::manual_seed(0);
  GaussianPolicy policy(GaussianPolicyOptions{1, 1, {2}, Activation::kRelu});
  // Zero every weight: mu = bias of the mean head's last layer, log std = that of the log-std head.
  {
    torch::NoGradGuard g;
    for (auto& p : policy->parameters())
      p.zero_();
    policy->mean_layers[1]->as<torch::nn::Linear>()->bias.fill_(0.2);
    policy->log_std_layers[1]->as<torch::nn::Linear>()->bias.fill_(-0.5);
  }
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

}  // namespace
}  // namespace hlt
