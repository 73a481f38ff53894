// Losses against hand-computed values, the policy density against its closed form, and every model's
// gradients against finite differences.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>
#include <functional>

#include "hlt/nn/batched_forward.h"
#include "hlt/nn/dense_chain.h"
#include "hlt/nn/dynamics_model.h"
#include "hlt/nn/gaussian_policy.h"
#include "hlt/nn/reward_model.h"
#include "hlt/nn/twin_q_network.h"
#include "hlt/util/error.h"
#include "support/gradient_check.h"

namespace hlt {
namespace {

using testing::expect_gradient_matches;

// Sets every parameter of `m` from a fixed pattern so hand computations are possible.
void set_params(torch::nn::Module& m, const std::map<std::string, torch::Tensor>& values) {
  torch::NoGradGuard g;
  for (auto& p : m.named_parameters()) {
    auto it = values.find(p.key());
    ASSERT_NE(it, values.end()) << "missing value for " << p.key();
    p.value().copy_(it->second);
  }
}

TEST(DynamicsModel, ForwardAndLossMatchHandComputation) {
  // n = 1, m = 1, hidden 2, sin: s' = s + w2 . sin(W1 [s, a] + b1) + b2.
  DynamicsModel model(DynamicsModelOptions{1, 1, 2, Activation::kSin});
  model->to(torch::kFloat64);
  set_params(*model, {{"fc1.weight", torch::tensor({{0.5, -1.0}, {2.0, 0.25}}, torch::kFloat64)},
                      {"fc1.bias", torch::tensor({0.1, -0.2}, torch::kFloat64)},
                      {"fc2.weight", torch::tensor({{1.5, -0.5}}, torch::kFloat64)},
                      {"fc2.bias", torch::tensor({0.3}, torch::kFloat64)},
                      {"log_std", torch::tensor({{0.2}}, torch::kFloat64)}});
  const double s = 0.7, a = -0.4, s_next = 1.9;
  const double h1 = std::sin(0.5 * s - 1.0 * a + 0.1), h2 = std::sin(2.0 * s + 0.25 * a - 0.2);
  const double pred = s + 1.5 * h1 - 0.5 * h2 + 0.3;
  auto S = torch::tensor({{s}}, torch::kFloat64), A = torch::tensor({{a}}, torch::kFloat64);
  EXPECT_NEAR(model->forward(S, A).item<double>(), pred, 1e-12);
  const double sigma = std::exp(0.2);
  const double nll = 0.5 * std::pow((s_next - pred) / sigma, 2) + 0.2 + 0.5 * std::log(2 * M_PI);
  EXPECT_NEAR(model->loss(S, A, torch::tensor({{s_next}}, torch::kFloat64)).item<double>(), nll, 1e-12);
  // The log-std is clamped to [-10, 2].
  {
    torch::NoGradGuard g;
    model->log_std_param.fill_(5.0);
  }
  EXPECT_DOUBLE_EQ(model->log_std().item<double>(), 2.0);
}

TEST(DynamicsModel, ReluVariantAndShapes) {
  DynamicsModel model(DynamicsModelOptions{3, 2, 16, Activation::kRelu});
  auto out = model->forward(torch::randn({5, 3}), torch::randn({5, 2}));
  EXPECT_EQ(out.sizes(), (std::vector<int64_t>{5, 3}));
  EXPECT_THROW(DynamicsModel(DynamicsModelOptions{0, 1}), Error);
  EXPECT_THROW(parse_activation("tanh"), Error);
}

TEST(RewardModel, TdLossMatchesHandComputation) {
  torch::manual_seed(3);
  RewardModel model(RewardModelOptions{2, 1, 8});
  model->to(torch::kFloat64);
  auto s = torch::randn({4, 2}, torch::kFloat64), a = torch::randn({4, 1}, torch::kFloat64);
  auto s2 = torch::randn({4, 2}, torch::kFloat64), a2 = torch::randn({4, 1}, torch::kFloat64);
  auto r = torch::tensor({{1.0}, {-2.0}, {0.5}, {0.0}}, torch::kFloat64);
  auto done = torch::tensor({{0.0}, {1.0}, {0.0}, {1.0}}, torch::kFloat64);
  auto q = model->forward(s, a), q2 = model->forward(s2, a2);
  double expected = 0;
  for (int i = 0; i < 4; ++i) {
    const double target =
        r[i][0].item<double>() + 0.95 * (1 - done[i][0].item<double>()) * q2[i][0].item<double>();
    expected += std::pow(target - q[i][0].item<double>(), 2) / 4;
  }
  EXPECT_NEAR(model->td_loss(s, a, r, s2, a2, done, 0.95).item<double>(), expected, 1e-12);
  // gamma = 0 is plain regression on the reward.
  const double plain = (r - q).square().mean().item<double>();
  EXPECT_NEAR(model->td_loss(s, a, r, s2, a2, done, 0.0).item<double>(), plain, 1e-12);
  // The target is detached: the gradient flows only through r(s, a).
  model->zero_grad();
  model->td_loss(s, a, r, s2, a2, done, 0.95).backward();
  auto g_full = model->fc1->weight.grad().clone();
  model->zero_grad();
  auto target = (r + 0.95 * (1 - done) * model->forward(s2, a2)).detach();
  (target - model->forward(s, a)).square().mean().backward();
  EXPECT_TRUE(torch::allclose(g_full, model->fc1->weight.grad()));
}

TEST(GaussianPolicy, LogProbMatchesClosedFormTanhGaussian) {
  torch::manual_seed(0);
  GaussianPolicy policy(GaussianPolicyOptions{3, 2, {16}, Activation::kSin});
  policy->to(torch::kFloat64);
  auto s = torch::randn({6, 3}, torch::kFloat64);
  auto [mean, log_std] = policy->forward(s);
  auto a = torch::rand({6, 2}, torch::kFloat64) * 1.8 - 0.9;
  auto lp = policy->log_prob(s, a);
  for (int i = 0; i < 6; ++i) {
    double expected = 0;
    for (int j = 0; j < 2; ++j) {
      const double ai = a[i][j].item<double>();
      const double u = std::atanh(ai);
      const double mu = mean[i][j].item<double>(), sd = std::exp(log_std[i][j].item<double>());
      // density of a = tanh(u): N(u; mu, sd) / |da/du|, da/du = 1 - a^2 (plus the 1e-6 guard).
      expected += -0.5 * std::pow((u - mu) / sd, 2) - std::log(sd * std::sqrt(2 * M_PI)) -
                  std::log(1 - ai * ai + 1e-6);
    }
    EXPECT_NEAR(lp[i][0].item<double>(), expected, 1e-9);
  }
}

TEST(GaussianPolicy, DensityIntegratesToOneIn1D) {
  torch::manual_seed(1);
  GaussianPolicy policy(GaussianPolicyOptions{2, 1, {8}, Activation::kSin});
  policy->to(torch::kFloat64);
  auto s = torch::randn({1, 2}, torch::kFloat64);
  const int n = 200001;
  auto a = torch::linspace(-1 + 1e-7, 1 - 1e-7, n, torch::kFloat64).view({n, 1});
  auto lp = policy->log_prob(s.expand({n, 2}), a);
  const double integral = torch::trapezoid(lp.exp().view({n}), a.view({n})).item<double>();
  EXPECT_NEAR(integral, 1.0, 1e-3);
}

TEST(GaussianPolicy, SamplesAreConsistentWithTheirLogProb) {
  torch::manual_seed(2);
  GaussianPolicy policy(GaussianPolicyOptions{4, 3, {128, 64}, Activation::kRelu});
  policy->to(torch::kFloat64);
  auto s = torch::randn({10, 4}, torch::kFloat64);
  PolicySample smp = policy->rsample(s);
  EXPECT_TRUE(smp.action.abs().lt(1).all().item<bool>());
  EXPECT_TRUE(torch::allclose(smp.action, torch::tanh(smp.pre_tanh)));
  EXPECT_TRUE(torch::allclose(smp.log_prob, policy->log_prob(s, smp.action), 1e-6, 1e-6));
  EXPECT_TRUE(smp.log_prob.requires_grad());
  EXPECT_FALSE(policy->sample(s).action.requires_grad());
  EXPECT_TRUE(torch::allclose(policy->mean_action(s), torch::tanh(policy->forward(s).first)));
  // Output layers start small: U(-3e-3, 3e-3), so the initial mean action is near 0.
  EXPECT_LT(policy->mean_action(s).abs().max().item<double>(), 0.1);
}

TEST(GaussianPolicy, LogStdIsClamped) {
  GaussianPolicy policy(GaussianPolicyOptions{1, 1, {4}, Activation::kSin});
  {
    torch::NoGradGuard g;
    for (auto& p : policy->log_std_layers->parameters())
      p.fill_(10.0);
  }
  EXPECT_DOUBLE_EQ(policy->forward(torch::ones({1, 1})).second.item<double>(), 2.0);
}

// Input normalisation is the same network applied to (s - offset) / scale, however the policy is evaluated:
// its own forward, the mean chain the deterministic planner differentiates, and the planners' batched pass.
TEST(GaussianPolicy, ClampWithInwardGradientPassesOnlyGradientsThatPointBackIntoRange) {
  // raw above hi, below lo and inside; upstream gradients of both signs. A descent step moves raw by -g:
  // above hi only g > 0 moves it back, below lo only g < 0.
  const auto raw = torch::tensor({3.0, 3.0, -7.0, -7.0, 0.5, 0.5, 2.0}, torch::requires_grad());
  const auto g = torch::tensor({1.0, -1.0, 1.0, -1.0, 1.0, -1.0, -2.0});
  const auto y = clamp_with_inward_gradient(raw, -5.0, 2.0);
  EXPECT_TRUE(torch::equal(y.detach(), raw.detach().clamp(-5.0, 2.0)));
  y.backward(g);
  EXPECT_TRUE(torch::equal(raw.grad(), torch::tensor({1.0, 0.0, 0.0, -1.0, 1.0, -1.0, -2.0})));
  EXPECT_THROW(clamp_with_inward_gradient(raw, 1.0, 0.0), Error);
}

TEST(GaussianPolicy, InputNormalisationIsTheNetworkOnScaledStates) {
  torch::manual_seed(3);
  const int64_t n = 4, m = 2;
  GaussianPolicyOptions o{n, m, {16, 8}, Activation::kRelu};
  GaussianPolicy raw(o);
  o.input_offset = {0.5, -0.1, 0.0, 7.0};
  o.input_scale = {0.05, 0.1, 1.0, 0.3};
  GaussianPolicy normalized(o);
  raw->to(torch::kFloat64);
  normalized->to(torch::kFloat64);
  {
    torch::NoGradGuard g;
    auto from = raw->parameters(), to = normalized->parameters();
    ASSERT_EQ(from.size(), to.size());
    for (size_t i = 0; i < from.size(); ++i)
      to[i].copy_(from[i] + 0.1);  // larger than the initial last layer, so the outputs differ
    for (size_t i = 0; i < from.size(); ++i)
      from[i].copy_(to[i]);
  }
  const auto s =
      torch::tensor({0.52, -0.05, 0.3, 7.4, 0.47, -0.2, -1.0, 6.5}, torch::kFloat64).reshape({2, n});
  const auto scaled =
      (s - torch::tensor(o.input_offset, torch::kFloat64)) / torch::tensor(o.input_scale, torch::kFloat64);
  // By hand for the first component: (0.52 - 0.5) / 0.05 = 0.4.
  EXPECT_NEAR(normalized->normalize(s)[0][0].item<double>(), 0.4, 1e-12);
  auto [mean, log_std] = normalized->forward(s);
  auto [raw_mean, raw_log_std] = raw->forward(scaled);
  EXPECT_TRUE(torch::allclose(mean, raw_mean, 1e-12, 1e-12));
  EXPECT_TRUE(torch::allclose(log_std, raw_log_std, 1e-12, 1e-12));
  EXPECT_FALSE(torch::allclose(normalized->mean_action(s), raw->mean_action(s), 1e-6, 1e-6));
  // The mean chain: values and the gradient with respect to the state (1 / scale times the raw network's).
  const auto x = s.clone().requires_grad_(true);
  const auto y = dense_chain(normalized->mean_chain(), {x});
  EXPECT_TRUE(torch::allclose(y, raw->mean_action(scaled), 1e-12, 1e-12));
  const auto gx = torch::autograd::grad({y.sum()}, {x})[0];
  const auto xs = scaled.clone().requires_grad_(true);
  const auto gs = torch::autograd::grad({raw->mean_action(xs).sum()}, {xs})[0];
  EXPECT_TRUE(torch::allclose(gx, gs / torch::tensor(o.input_scale, torch::kFloat64), 1e-10, 1e-10));
  // Asking for the chain draws nothing from the default generator.
  torch::manual_seed(9);
  normalized->mean_chain();
  const double after = torch::rand({1}, torch::kFloat64).item<double>();
  torch::manual_seed(9);
  EXPECT_EQ(after, torch::rand({1}, torch::kFloat64).item<double>());
  // The planners' batched pass.
  PolicyForward pf(normalized);
  pf.prepare(2);
  pf.forward(s);
  EXPECT_TRUE(torch::allclose(pf.mean(), mean, 1e-12, 1e-12));
  EXPECT_TRUE(torch::allclose(pf.log_std(), log_std, 1e-12, 1e-12));
}

// With references, component i is read relative to component r(i) first: the same network on
// ((s_i - s_r(i)) - offset) / scale, in all three ways of evaluating it, and the state gradient follows the
// chain rule through the difference.
TEST(GaussianPolicy, InputReferencesAreTheNetworkOnRelativeStates) {
  torch::manual_seed(4);
  const int64_t n = 4, m = 2;
  GaussianPolicyOptions o{n, m, {16, 8}, Activation::kRelu};
  GaussianPolicy raw(o);
  o.input_offset = {0.5, 0.0, 0.1, 0.0};
  o.input_scale = {0.05, 0.01, 0.2, 0.5};
  o.input_reference = {-1, 0, -1, 1};  // s1 - s0, and s3 - s1 (the raw s1)
  GaussianPolicy relative(o);
  raw->to(torch::kFloat64);
  relative->to(torch::kFloat64);
  {
    torch::NoGradGuard g;
    auto from = raw->parameters(), to = relative->parameters();
    for (size_t i = 0; i < from.size(); ++i)
      to[i].copy_(from[i] + 0.1);
    for (size_t i = 0; i < from.size(); ++i)
      from[i].copy_(to[i]);
  }
  const auto s =
      torch::tensor({0.52, 0.525, 0.3, 1.2, 0.47, 0.468, -1.0, 0.2}, torch::kFloat64).reshape({2, n});
  auto by_hand = [&](const torch::Tensor& x) {
    const auto c = x.unbind(1);
    const auto rel = torch::stack({c[0], c[1] - c[0], c[2], c[3] - c[1]}, 1);
    return (rel - torch::tensor(o.input_offset, torch::kFloat64)) /
           torch::tensor(o.input_scale, torch::kFloat64);
  };
  // By hand: (0.525 - 0.52 - 0) / 0.01 = 0.5 and (1.2 - 0.525 - 0) / 0.5 = 1.35.
  EXPECT_NEAR(relative->normalize(s)[0][1].item<double>(), 0.5, 1e-12);
  EXPECT_NEAR(relative->normalize(s)[0][3].item<double>(), 1.35, 1e-12);
  auto [mean, log_std] = relative->forward(s);
  auto [raw_mean, raw_log_std] = raw->forward(by_hand(s));
  EXPECT_TRUE(torch::allclose(mean, raw_mean, 1e-12, 1e-12));
  EXPECT_TRUE(torch::allclose(log_std, raw_log_std, 1e-12, 1e-12));
  const auto x = s.clone().requires_grad_(true);
  const auto y = dense_chain(relative->mean_chain(), {x});
  const auto xh = s.clone().requires_grad_(true);
  const auto yh = raw->mean_action(by_hand(xh));
  EXPECT_TRUE(torch::allclose(y, yh, 1e-12, 1e-12));
  const auto gx = torch::autograd::grad({y.sum()}, {x})[0];
  const auto gh = torch::autograd::grad({yh.sum()}, {xh})[0];
  EXPECT_TRUE(torch::allclose(gx, gh, 1e-10, 1e-10));
  PolicyForward pf(relative);
  pf.prepare(2);
  pf.forward(s);
  EXPECT_TRUE(torch::allclose(pf.mean(), mean, 1e-12, 1e-12));
  EXPECT_TRUE(torch::allclose(pf.log_std(), log_std, 1e-12, 1e-12));
}

TEST(GaussianPolicy, BadInputNormalisationIsAnError) {
  {
    GaussianPolicyOptions o{2, 1, {4}, Activation::kRelu};
    o.input_reference = {-1, 0};
    EXPECT_THROW(GaussianPolicy{o}, Error);  // references without the normalisation
    o.input_offset = {0.0, 0.0};
    o.input_scale = {1.0, 1.0};
    EXPECT_NO_THROW(GaussianPolicy{o});
    o.input_reference = {-1, 1};
    EXPECT_THROW(GaussianPolicy{o}, Error);  // relative to itself
    o.input_reference = {-1, 2};
    EXPECT_THROW(GaussianPolicy{o}, Error);  // no such component
    o.input_reference = {-1};
    EXPECT_THROW(GaussianPolicy{o}, Error);  // one of two
  }
  GaussianPolicyOptions o{2, 1, {4}, Activation::kRelu};
  o.input_offset = {0.0};
  o.input_scale = {1.0};
  EXPECT_THROW(GaussianPolicy{o}, Error);  // one of two components
  o.input_offset = {0.0, 0.0};
  o.input_scale = {1.0, 0.0};
  EXPECT_THROW(GaussianPolicy{o}, Error);  // a zero scale
  o.input_scale = {1.0, std::nan("")};
  EXPECT_THROW(GaussianPolicy{o}, Error);
  o.input_scale = {1.0, 2.0};
  o.input_offset = {};
  EXPECT_THROW(GaussianPolicy{o}, Error);  // scales without offsets
}

TEST(TwinQNetwork, EachCriticIsItsOwnReluMlp) {
  torch::manual_seed(2);
  const int n = 3, m = 2, B = 5;
  TwinQNetwork q(TwinQNetworkOptions{n, m, {7, 4}});
  ASSERT_EQ(q->weights.size(), 3u);
  EXPECT_EQ(q->weights[0].sizes(), (std::vector<int64_t>{2, n + m, 7}));
  EXPECT_EQ(q->biases[2].sizes(), (std::vector<int64_t>{2, 1, 1}));
  // The two critics are initialised independently.
  EXPECT_GT((q->weights[1][0] - q->weights[1][1]).abs().max().item<double>(), 1e-3);
  auto s = torch::randn({B, n}), a = torch::randn({B, m});
  const auto out = q->forward(s, a);
  ASSERT_EQ(out.sizes(), (std::vector<int64_t>{2, B, 1}));
  for (int i = 0; i < 2; ++i) {
    auto x = torch::cat({s, a}, 1);
    x = torch::relu(x.mm(q->weights[0][i]) + q->biases[0][i]);
    x = torch::relu(x.mm(q->weights[1][i]) + q->biases[1][i]);
    x = x.mm(q->weights[2][i]) + q->biases[2][i];
    EXPECT_TRUE(torch::allclose(out[i], x, 1e-5, 1e-6)) << i;
  }
  EXPECT_TRUE(torch::equal(q->min_q(s, a), torch::min(out[0], out[1])));
}

TEST(Gradients, EveryModelMatchesFiniteDifferences) {
  torch::manual_seed(4);
  const int n = 3, m = 2;
  DynamicsModel dyn(DynamicsModelOptions{n, m, 12, Activation::kSin});
  RewardModel rew(RewardModelOptions{n, m, 10});
  GaussianPolicy pol(GaussianPolicyOptions{n, m, {9, 7}, Activation::kSin});
  TwinQNetwork q(TwinQNetworkOptions{n, m, {11, 6}});
  for (torch::nn::Module* mod :
       std::initializer_list<torch::nn::Module*>{dyn.get(), rew.get(), pol.get(), q.get()}) {
    mod->to(torch::kFloat64);
  }
  auto s = torch::randn({4, n}, torch::kFloat64), a = torch::rand({4, m}, torch::kFloat64) * 1.6 - 0.8;
  auto s2 = torch::randn({4, n}, torch::kFloat64);
  // With respect to inputs.
  expect_gradient_matches([&](const torch::Tensor& x) { return dyn->forward(x, a).square().sum(); }, s);
  expect_gradient_matches([&](const torch::Tensor& x) { return dyn->loss(s, x, s2); }, a);
  expect_gradient_matches([&](const torch::Tensor& x) { return rew->forward(s, x).sum(); }, a, 1e-5);
  expect_gradient_matches([&](const torch::Tensor& x) { return pol->log_prob(x, a).sum(); }, s);
  expect_gradient_matches([&](const torch::Tensor& x) { return pol->mean_action(x).sum(); }, s);
  expect_gradient_matches([&](const torch::Tensor& x) { return q->forward(x, a).sum(); }, s, 1e-5);
  // With respect to parameters: the dynamics log-std through the NLL, and the policy's first mean layer.
  auto check_param = [&](torch::Tensor param, const std::function<torch::Tensor()>& loss) {
    auto g = torch::autograd::grad({loss()}, {param})[0];
    auto fd = testing::finite_difference_gradient(
        [&](const torch::Tensor& v) {
          torch::NoGradGuard ng;
          auto saved = param.clone();
          param.copy_(v);
          auto out = loss();
          param.copy_(saved);
          return out;
        },
        param);
    EXPECT_LT(testing::relative_error(g, fd), 1e-6);
  };
  check_param(dyn->log_std_param, [&] { return dyn->loss(s, a, s2); });
  check_param(pol->mean_layers[0]->as<torch::nn::Linear>()->weight,
              [&] { return pol->log_prob(s, a).sum(); });
  // gamma = 0: with a bootstrapped target the loss is a semi-gradient (target detached), which finite
  // differences of the full loss would not reproduce; the detach itself is tested above.
  check_param(rew->fc2->weight, [&] {
    return rew->td_loss(s, a, torch::ones({4, 1}, torch::kFloat64), s2, a,
                        torch::zeros({4, 1}, torch::kFloat64), 0.0);
  });
}

// The hand-written backward passes the model learner uses against autograd on the same loss: every
// parameter's gradient, in float64 so that only the formulas can differ.
std::vector<torch::Tensor> autograd_gradients(torch::nn::Module& m, const torch::Tensor& loss) {
  return torch::autograd::grad({loss}, m.parameters());
}

void expect_written_gradients(torch::nn::Module& m, const std::vector<torch::Tensor>& expected) {
  const auto params = m.parameters();
  ASSERT_EQ(params.size(), expected.size());
  for (size_t i = 0; i < params.size(); ++i) {
    ASSERT_TRUE(params[i].grad().defined()) << m.named_parameters().keys()[i];
    EXPECT_LT(testing::relative_error(params[i].grad(), expected[i]), 1e-12)
        << m.named_parameters().keys()[i];
  }
}

TEST(HandWrittenGradients, DynamicsLossMatchesAutograd) {
  for (Activation act : {Activation::kSin, Activation::kRelu}) {
    torch::manual_seed(5);
    const int n = 3, m = 2, B = 7;
    DynamicsModel dyn(DynamicsModelOptions{n, m, 12, act, -1.0, 0.5});
    dyn->to(torch::kFloat64);
    {
      // One log-std entry beyond each clamp bound: their gradients must be zero.
      torch::NoGradGuard ng;
      dyn->log_std_param.copy_(torch::tensor({{-1.5, 0.2, 0.9}}, torch::kFloat64));
    }
    auto s = torch::randn({B, n}, torch::kFloat64), a = torch::randn({B, m}, torch::kFloat64);
    auto s2 = s + 0.3 * torch::randn({B, n}, torch::kFloat64);
    const torch::Tensor loss = dyn->loss(s, a, s2);
    auto expected = autograd_gradients(*dyn, 0.25 * loss);
    EXPECT_NEAR(dyn->loss_with_gradient(s, a, s2, 0.25), loss.item<double>(), 1e-12);
    expect_written_gradients(*dyn, expected);
    EXPECT_EQ(dyn->log_std_param.grad()[0][0].item<double>(), 0.0);
    EXPECT_EQ(dyn->log_std_param.grad()[0][2].item<double>(), 0.0);
    EXPECT_NE(dyn->log_std_param.grad()[0][1].item<double>(), 0.0);
    // A second call overwrites the gradients rather than adding to them.
    dyn->loss_with_gradient(s, a, s2, 0.25);
    expect_written_gradients(*dyn, expected);
  }
}

// The open-loop loss: one step is loss(); K steps are the mean of loss() along the model's own predictions;
// data the model itself generated leaves only the log-std terms; the gradient it writes matches finite
// differences through all K predictions (float64).
TEST(DynamicsModel, RolloutLossIsTheMeanLikelihoodAlongTheModelsOwnPredictions) {
  torch::manual_seed(6);
  const int n = 3, m = 2, B = 5, K = 4;
  DynamicsModel dyn(DynamicsModelOptions{n, m, 12, Activation::kSin, -1.0, 0.5});
  dyn->to(torch::kFloat64);
  {
    torch::NoGradGuard ng;
    dyn->log_std_param.copy_(torch::tensor({{-0.3, 0.2, 0.1}}, torch::kFloat64));
  }
  auto s0 = torch::randn({B, n}, torch::kFloat64);
  auto actions = torch::randn({K * B, m}, torch::kFloat64);
  auto next_states = torch::randn({K * B, n}, torch::kFloat64);
  // One step.
  EXPECT_NEAR(dyn->rollout_loss(s0, actions.narrow(0, 0, B), next_states.narrow(0, 0, B)).item<double>(),
              dyn->loss(s0, actions.narrow(0, 0, B), next_states.narrow(0, 0, B)).item<double>(), 1e-14);
  // K steps, composed by hand.
  double expected = 0;
  torch::Tensor predicted = s0, own = torch::empty({K * B, n}, torch::kFloat64);
  {
    torch::NoGradGuard ng;
    for (int k = 0; k < K; ++k) {
      const auto a = actions.narrow(0, k * B, B);
      expected += dyn->loss(predicted, a, next_states.narrow(0, k * B, B)).item<double>() / K;
      predicted = dyn->forward(predicted, a);
      own.narrow(0, k * B, B).copy_(predicted);
    }
  }
  EXPECT_NEAR(dyn->rollout_loss(s0, actions, next_states).item<double>(), expected, 1e-12);
  // On its own rollout only mean(log sigma) + log(2 pi) / 2 remains.
  EXPECT_NEAR(dyn->rollout_loss(s0, actions, own).item<double>(),
              (-0.3 + 0.2 + 0.1) / 3 + 0.5 * std::log(2 * M_PI), 1e-12);
  // The written gradient against finite differences of the loss, for every parameter.
  EXPECT_NEAR(dyn->rollout_loss_with_gradient(s0, actions, next_states, 0.5), expected, 1e-12);
  for (auto& named : dyn->named_parameters()) {
    torch::Tensor param = named.value();
    const auto fd = testing::finite_difference_gradient(
        [&](const torch::Tensor& v) {
          torch::NoGradGuard ng;
          auto saved = param.clone();
          param.copy_(v);
          auto out = dyn->rollout_loss(s0, actions, next_states);
          param.copy_(saved);
          return out;
        },
        param);
    EXPECT_LT(testing::relative_error(param.grad(), 0.5 * fd), 1e-6) << named.key();
  }
  // Shapes that do not split into K steps of B are refused; so is a call inside inference mode.
  EXPECT_THROW(dyn->rollout_loss(s0, actions.narrow(0, 0, 7), next_states.narrow(0, 0, 7)), Error);
  c10::InferenceMode guard;
  EXPECT_THROW(dyn->rollout_loss_with_gradient(s0, actions, next_states), Error);
}

TEST(HandWrittenGradients, RewardTdLossMatchesAutograd) {
  for (double gamma : {0.0, 0.95}) {
    torch::manual_seed(6);
    const int n = 3, m = 2, B = 9;
    RewardModel rew(RewardModelOptions{n, m, 10});
    rew->to(torch::kFloat64);
    auto s = torch::randn({B, n}, torch::kFloat64), a = torch::randn({B, m}, torch::kFloat64);
    auto s2 = torch::randn({B, n}, torch::kFloat64), a2 = torch::randn({B, m}, torch::kFloat64);
    auto r = torch::randn({B, 1}, torch::kFloat64);
    auto done = (torch::rand({B, 1}, torch::kFloat64) < 0.3).to(torch::kFloat64);
    const torch::Tensor loss = rew->td_loss(s, a, r, s2, a2, done, gamma);
    auto expected = autograd_gradients(*rew, 0.5 * loss);
    EXPECT_NEAR(rew->td_loss_with_gradient(s, a, r, s2, a2, done, gamma, 0.5), loss.item<double>(), 1e-12);
    expect_written_gradients(*rew, expected);
  }
}

// The learned models' input normalisation: the same networks on x(s) = (s relative to its references -
// offset) / scale in every way they are evaluated (module forward, the model learner's hand-written passes,
// the deterministic planner's autograd chains, the planners' batched pass), the dynamics' residual adding
// the raw state.
TEST(LearnedModels, InputNormalisationIsTheNetworkOnScaledStates) {
  torch::manual_seed(7);
  const int64_t n = 4, m = 2, B = 5;
  DynamicsModelOptions dop{n, m, 12, Activation::kRelu};
  RewardModelOptions rop{n, m, 10};
  DynamicsModel dyn_raw(dop);
  RewardModel rew_raw(rop);
  const std::vector<double> offset = {0.5, 0.0, 0.1, 0.0}, scale = {0.05, 0.01, 0.2, 0.5};
  const std::vector<int64_t> reference = {-1, 0, -1, 1};  // s1 - s0, and s3 - s1 (the raw s1)
  dop.input_offset = rop.input_offset = offset;
  dop.input_scale = rop.input_scale = scale;
  dop.input_reference = rop.input_reference = reference;
  DynamicsModel dyn(dop);
  RewardModel rew(rop);
  for (torch::nn::Module* mod :
       std::initializer_list<torch::nn::Module*>{dyn_raw.get(), rew_raw.get(), dyn.get(), rew.get()})
    mod->to(torch::kFloat64);
  {
    torch::NoGradGuard g;
    for (auto [from, to] : {std::pair<torch::nn::Module*, torch::nn::Module*>{dyn_raw.get(), dyn.get()},
                            std::pair<torch::nn::Module*, torch::nn::Module*>{rew_raw.get(), rew.get()}}) {
      auto f = from->parameters(), t = to->parameters();
      ASSERT_EQ(f.size(), t.size());
      for (size_t i = 0; i < f.size(); ++i)
        t[i].copy_(f[i]);
    }
  }
  const auto s =
      (torch::tensor({0.5, 0.51, 0.0, 0.6}, torch::kFloat64) + 0.02 * torch::randn({B, n}, torch::kFloat64))
          .contiguous();
  const auto a = (torch::rand({B, m}, torch::kFloat64) * 2 - 1).contiguous();
  const auto s2 = (s + 0.01 * torch::randn({B, n}, torch::kFloat64)).contiguous();
  const auto a2 = (torch::rand({B, m}, torch::kFloat64) * 2 - 1).contiguous();
  const auto r = torch::randn({B, 1}, torch::kFloat64);
  const auto done = (torch::rand({B, 1}, torch::kFloat64) < 0.3).to(torch::kFloat64);
  auto by_hand = [&](const torch::Tensor& x) {
    const auto c = x.unbind(1);
    const auto rel = torch::stack({c[0], c[1] - c[0], c[2], c[3] - c[1]}, 1);
    return (rel - torch::tensor(offset, torch::kFloat64)) / torch::tensor(scale, torch::kFloat64);
  };
  // Module forward: the raw model's network (its forward less its residual) on x(s), plus the raw state.
  const auto x = by_hand(s);
  EXPECT_TRUE(torch::allclose(dyn->forward(s, a), s + (dyn_raw->forward(x, a) - x), 1e-12, 1e-12));
  EXPECT_TRUE(torch::allclose(rew->forward(s, a), rew_raw->forward(x, a), 1e-12, 1e-12));
  EXPECT_FALSE(torch::allclose(rew->forward(s, a), rew_raw->forward(s, a), 1e-6, 1e-6));
  // The hand-written loss passes against autograd through the normalised forward.
  const torch::Tensor dyn_loss = dyn->loss(s, a, s2);
  const auto dyn_expected = autograd_gradients(*dyn, dyn_loss);
  EXPECT_NEAR(dyn->loss_with_gradient(s, a, s2), dyn_loss.item<double>(), 1e-12);
  expect_written_gradients(*dyn, dyn_expected);
  const torch::Tensor rew_loss = rew->td_loss(s, a, r, s2, a2, done, 0.9);
  const auto rew_expected = autograd_gradients(*rew, rew_loss);
  EXPECT_NEAR(rew->td_loss_with_gradient(s, a, r, s2, a2, done, 0.9), rew_loss.item<double>(), 1e-12);
  expect_written_gradients(*rew, rew_expected);
  // The chains: values, and gradients with respect to state and action through the normalisation.
  for (auto [chain, forward] :
       {std::pair<DenseChain, std::function<torch::Tensor(const torch::Tensor&, const torch::Tensor&)>>{
            dyn->chain(), [&](const torch::Tensor&u, const torch::Tensor&v) { return dyn->forward(u, v); }},
        std::pair<DenseChain, std::function<torch::Tensor(const torch::Tensor&, const torch::Tensor&)>>{
            rew->chain(),
            [&](const torch::Tensor&u, const torch::Tensor&v) { return rew->forward(u, v); }}}) {
    const auto sc = s.clone().requires_grad_(true), ac = a.clone().requires_grad_(true);
    const auto sr = s.clone().requires_grad_(true), ar = a.clone().requires_grad_(true);
    const auto y = dense_chain(chain, {sc, ac}), y_ref = forward(sr, ar);
    EXPECT_TRUE(torch::allclose(y, y_ref, 1e-12, 1e-12));
    const auto w = torch::randn(y.sizes(), torch::kFloat64);
    const auto g = torch::autograd::grad({(y * w).sum()}, {sc, ac});
    const auto g_ref = torch::autograd::grad({(y_ref * w).sum()}, {sr, ar});
    EXPECT_TRUE(torch::allclose(g[0], g_ref[0], 1e-9, 1e-9));
    EXPECT_TRUE(torch::allclose(g[1], g_ref[1], 1e-9, 1e-9));
  }
  // The planners' batched pass.
  ModelForward mf(dyn, rew);
  mf.prepare(B);
  auto next = torch::empty({B, n}, torch::kFloat64), rewards = torch::empty({B}, torch::kFloat64);
  mf.step(s, a, next, &rewards);
  EXPECT_TRUE(torch::allclose(next, dyn->forward(s, a), 1e-12, 1e-12));
  EXPECT_TRUE(torch::allclose(rewards, rew->forward(s, a).squeeze(1), 1e-12, 1e-12));
  // One pass reads both models' first layers from one input: their normalisations must agree.
  EXPECT_THROW(ModelForward(dyn, rew_raw), Error);
  // Bad normalisations are errors, as for the policy.
  dop.input_scale = {0.05, 0.0, 0.2, 0.5};
  EXPECT_THROW(DynamicsModel{dop}, Error);
  rop.input_reference = {-1, 1, -1, 1};
  EXPECT_THROW(RewardModel{rop}, Error);
}

}  // namespace
}  // namespace hlt
