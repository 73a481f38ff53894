// dense_chain (one autograd node per network) against autograd through the modules' own forward passes and
// against finite differences.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include "hlt/nn/dense_chain.h"
#include "hlt/nn/dynamics_model.h"
#include "hlt/nn/gaussian_policy.h"
#include "hlt/nn/reward_model.h"
#include "hlt/util/error.h"
#include "support/error_of.h"
#include "support/gradient_check.h"

namespace hlt {
namespace {

// One network under test: its chain, the module's forward on the same inputs, and the inputs' widths.
struct Case {
  std::string name;
  DenseChain chain;
  std::function<torch::Tensor(const std::vector<torch::Tensor>&)> module_forward;
  std::vector<int64_t> widths;
};

std::vector<Case> cases(torch::Dtype dtype) {
  torch::manual_seed(3);
  const int64_t n = 4, m = 2;
  std::vector<Case> out;
  for (Activation act : {Activation::kSin, Activation::kRelu}) {
    DynamicsModel f(DynamicsModelOptions{n, m, 16, act});
    f->to(dtype);
    out.push_back({"dynamics_" + activation_name(act),
                   f->chain(),
                   [f](const std::vector<torch::Tensor>& x) mutable { return f->forward(x[0], x[1]); },
                   {n, m}});
    GaussianPolicy pi(GaussianPolicyOptions{n, m, {16, 8}, act});
    pi->to(dtype);
    out.push_back({"policy_mean_" + activation_name(act),
                   pi->mean_chain(),
                   [pi](const std::vector<torch::Tensor>& x) mutable { return pi->mean_action(x[0]); },
                   {n}});
  }
  RewardModel r(RewardModelOptions{n, m, 16});
  r->to(dtype);
  out.push_back({"reward",
                 r->chain(),
                 [r](const std::vector<torch::Tensor>& x) mutable { return r->forward(x[0], x[1]); },
                 {n, m}});
  return out;
}

std::vector<torch::Tensor> random_inputs(const Case& c, int64_t batch, torch::Dtype dtype) {
  std::vector<torch::Tensor> x;
  for (int64_t w : c.widths)
    x.push_back(torch::randn({batch, w}, dtype).requires_grad_(true));
  return x;
}

// The inputs, then every layer's weight and bias: everything a chain's gradient reaches.
std::vector<torch::Tensor> inputs_and_parameters(const Case& c, const std::vector<torch::Tensor>& x) {
  std::vector<torch::Tensor> wrt = x;
  for (const auto& layer : c.chain.layers) {
    wrt.push_back(layer->weight);
    wrt.push_back(layer->bias);
  }
  return wrt;
}

TEST(DenseChain, ValuesAndEveryGradientMatchAutogradThroughTheModule) {
  for (Case& c : cases(torch::kFloat64)) {
    SCOPED_TRACE(c.name);
    const auto x = random_inputs(c, 7, torch::kFloat64);
    const torch::Tensor y = dense_chain(c.chain, x);
    const torch::Tensor y_ref = c.module_forward(x);
    ASSERT_EQ(y.sizes(), y_ref.sizes());
    EXPECT_LT((y - y_ref).abs().max().item<double>(), 1e-12);

    // A random seed, gradients with respect to the inputs and all the parameters.
    const torch::Tensor seed = torch::randn_like(y);
    const std::vector<torch::Tensor> wrt = inputs_and_parameters(c, x);
    const auto g = torch::autograd::grad({y}, wrt, {seed});
    const auto g_ref = torch::autograd::grad({y_ref}, wrt, {seed});
    ASSERT_EQ(g.size(), g_ref.size());
    for (size_t i = 0; i < g.size(); ++i) {
      ASSERT_TRUE(g[i].defined()) << "gradient " << i;
      EXPECT_LT(testing::relative_error(g[i], g_ref[i]), 1e-12) << "gradient " << i;
    }
  }
}

TEST(DenseChain, InputGradientsMatchFiniteDifferences) {
  for (Case& c : cases(torch::kFloat64)) {
    SCOPED_TRACE(c.name);
    auto x = random_inputs(c, 3, torch::kFloat64);
    for (size_t i = 0; i < x.size(); ++i) {
      // A scalar function of input i: a fixed weighting of the outputs.
      const torch::Tensor weights = torch::randn({3, c.chain.layers.back()->weight.size(0)}, torch::kFloat64);
      testing::expect_gradient_matches(
          [&](const torch::Tensor& xi) {
            std::vector<torch::Tensor> in = x;
            in[i] = xi;
            return (dense_chain(c.chain, in) * weights).sum();
          },
          x[i].detach(), 1e-7);
    }
  }
}

TEST(DenseChain, FloatValuesMatchTheModule) {
  for (Case& c : cases(torch::kFloat32)) {
    SCOPED_TRACE(c.name);
    const auto x = random_inputs(c, 33, torch::kFloat32);
    const torch::Tensor y = dense_chain(c.chain, x), y_ref = c.module_forward(x);
    EXPECT_LT((y - y_ref).abs().max().item<double>(), 1e-5);
    // The float path has its own kernels (vector sin and cos, the ReLU mask pass): its gradients too.
    const torch::Tensor seed = torch::randn_like(y);
    const std::vector<torch::Tensor> wrt = inputs_and_parameters(c, x);
    const auto g = torch::autograd::grad({y}, wrt, {seed}),
               g_ref = torch::autograd::grad({y_ref}, wrt, {seed});
    for (size_t i = 0; i < g.size(); ++i)
      EXPECT_LT(testing::relative_error(g[i], g_ref[i]), 1e-5) << "gradient " << i;
  }
}

TEST(DenseChain, StridedInputsAndSeedsGiveTheSameResults) {
  Case c = cases(torch::kFloat64).front();  // dynamics: a residual and two inputs
  const auto wide_s = torch::randn({5, 8}, torch::kFloat64), wide_a = torch::randn({2, 5}, torch::kFloat64);
  const torch::Tensor s = wide_s.narrow(1, 2, 4).requires_grad_(false), a = wide_a.t();  // strided views
  const torch::Tensor sc = s.contiguous().requires_grad_(true), ac = a.contiguous().requires_grad_(true);
  const torch::Tensor sv = s.detach().requires_grad_(true), av = a.detach().requires_grad_(true);
  const torch::Tensor y = dense_chain(c.chain, {sv, av}), y_ref = c.module_forward({sc, ac});
  EXPECT_LT((y - y_ref).abs().max().item<double>(), 1e-12);
  // An expanded seed (stride 0), as torch::ones(...).expand gives.
  const torch::Tensor seed = torch::randn({1, 4}, torch::kFloat64).expand({5, 4});
  const auto g = torch::autograd::grad({y}, {sv, av}, {seed}),
             g_ref = torch::autograd::grad({y_ref}, {sc, ac}, {seed});
  EXPECT_LT(testing::relative_error(g[0], g_ref[0]), 1e-12);
  EXPECT_LT(testing::relative_error(g[1], g_ref[1]), 1e-12);
}

TEST(DenseChain, OnlyWhatIsAskedForIsComputedAndWeightsNeedNoGradient) {
  Case c = cases(torch::kFloat64).back();  // the reward model
  auto x = random_inputs(c, 5, torch::kFloat64);
  x[1] = x[1].detach();  // the action needs no gradient
  const torch::Tensor y = dense_chain(c.chain, x);
  const auto g = torch::autograd::grad({y}, {x[0]}, {torch::ones_like(y)});
  const auto g_ref = torch::autograd::grad({c.module_forward(x)}, {x[0]}, {torch::ones_like(y)});
  EXPECT_LT(testing::relative_error(g[0], g_ref[0]), 1e-12);
  // Without gradient mode the result is a plain tensor.
  torch::NoGradGuard no_grad;
  EXPECT_FALSE(dense_chain(c.chain, x).requires_grad());
}

TEST(DenseChain, AWeightChangedInPlaceBeforeTheBackwardPassIsAnError) {
  Case c = cases(torch::kFloat64).front();
  const auto x = random_inputs(c, 5, torch::kFloat64);
  const torch::Tensor y = dense_chain(c.chain, x);
  {
    torch::NoGradGuard no_grad;
    c.chain.layers[0]->weight.add_(1.0);
  }
  EXPECT_THROW(torch::autograd::grad({y.sum()}, {x[0]}), c10::Error);
}

// The node must not hold its own output: a strong reference from the node to the output it is the grad_fn of
// is a cycle that neither refcount ever breaks, and every call would leak its whole graph (the deterministic
// planner lost ~36 KB per action this way). Once the output and the inputs are gone, the node is gone too.
TEST(DenseChain, TheGraphIsFreedWithItsOutput) {
  for (Case& c : cases(torch::kFloat64)) {
    SCOPED_TRACE(c.name);
    std::weak_ptr<torch::autograd::Node> node;
    {
      const auto x = random_inputs(c, 3, torch::kFloat64);
      const torch::Tensor y = dense_chain(c.chain, x);
      node = y.grad_fn();
      ASSERT_FALSE(node.expired());
    }
    EXPECT_TRUE(node.expired());
  }
}

TEST(DenseChain, BadInputsAreClearErrors) {
  Case c = cases(torch::kFloat64).front();  // dynamics: takes n + m = 6 columns, residual of width 4
  const auto wide = torch::randn({2, 5}, torch::kFloat64), a = torch::randn({2, 2}, torch::kFloat64);
  EXPECT_NE(testing::error_of([&] { dense_chain(c.chain, {wide, a}); }).find("7 columns"), std::string::npos);
  EXPECT_NE(testing::error_of([&] { dense_chain(c.chain, {}); }).find("no inputs"), std::string::npos);
  EXPECT_NE(
      testing::error_of([&] {
        dense_chain(c.chain, {torch::randn({2, 4}, torch::kFloat64), torch::randn({3, 2}, torch::kFloat64)});
      }).find("one B"),
      std::string::npos);
  EXPECT_NE(testing::error_of([&] { dense_chain(DenseChain{}, {a}); }).find("no layers"), std::string::npos);
}

}  // namespace
}  // namespace hlt
