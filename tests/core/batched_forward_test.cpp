// The planners' batched forward passes against the modules' own forward passes.
#include "hlt/nn/batched_forward.h"

#include <gtest/gtest.h>
#include <torch/torch.h>

namespace hlt {
namespace {

class BatchedForward
    : public ::testing::TestWithParam<std::tuple<torch::Dtype, Activation, std::vector<int64_t>>> {};

TEST_P(BatchedForward, MatchesModuleForward) {
  const auto [dtype, act, hidden] = GetParam();
  torch::manual_seed(0);
  const int64_t n = 7, m = 3, B = 11;
  GaussianPolicy policy(GaussianPolicyOptions{n, m, hidden, act});
  DynamicsModel dyn(DynamicsModelOptions{n, m, 40, act});
  RewardModel rew(RewardModelOptions{n, m, 30});
  policy->to(dtype);
  dyn->to(dtype);
  rew->to(dtype);
  {
    // Log-std outputs that reach both clamps ([-5, 2]) in the first two dimensions.
    torch::NoGradGuard g;
    policy->log_std_layers[hidden.size()]->as<torch::nn::Linear>()->bias.copy_(
        torch::tensor({9.0, -12.0, 0.0}));
  }
  const auto s = torch::randn({B, n}, dtype) * 2, a = torch::rand({B, m}, dtype) * 2 - 1;
  PolicyForward pf(policy);
  ModelForward mf(dyn, rew);
  // Twice, with the weights changed in between: prepare() must pick up the new values.
  for (int round = 0; round < 2; ++round) {
    torch::NoGradGuard g;
    pf.prepare(B);
    mf.prepare(B);
    pf.forward(s);
    auto [mean, log_std] = policy->forward(s);
    const double tol = dtype == torch::kFloat64 ? 1e-12 : 1e-5;
    EXPECT_TRUE(torch::allclose(pf.mean(), mean, tol, tol));
    EXPECT_TRUE(torch::allclose(pf.log_std(), log_std, tol, tol));
    EXPECT_GT((log_std == policy->options().log_std_max).sum().item<int64_t>() +
                  (log_std == policy->options().log_std_min).sum().item<int64_t>(),
              0);
    auto next = torch::empty({B, n}, s.options()), r = torch::empty({B}, s.options());
    mf.step(s, a, next, &r);
    EXPECT_TRUE(torch::allclose(next, dyn->forward(s, a), tol, tol));
    EXPECT_TRUE(torch::allclose(r, rew->forward(s, a).squeeze(1), tol, tol));
    for (auto& p : policy->parameters())
      p.mul_(1.1);
    for (auto& p : dyn->parameters())
      p.mul_(0.9);
    for (auto& p : rew->parameters())
      p.add_(0.01);
  }
}

INSTANTIATE_TEST_SUITE_P(
    AllConfigurations, BatchedForward,
    ::testing::Values(std::make_tuple(torch::kFloat32, Activation::kSin, std::vector<int64_t>{128}),
                      std::make_tuple(torch::kFloat64, Activation::kSin, std::vector<int64_t>{16}),
                      std::make_tuple(torch::kFloat32, Activation::kRelu, std::vector<int64_t>{128, 64}),
                      std::make_tuple(torch::kFloat64, Activation::kRelu, std::vector<int64_t>{32, 24, 8})));

TEST(BatchedForwardErrors, RejectsIntegerTensors) {
  EXPECT_THROW(dispatch_floating(torch::zeros({2}, torch::kInt64), [](auto) {}), std::exception);
}

}  // namespace
}  // namespace hlt
