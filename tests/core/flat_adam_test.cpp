// FlatAdam against LibTorch's own Adam on the same problem, the gradient binding autograd accumulates into,
// and its checkpoint round trip.
#include "hlt/nn/flat_adam.h"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <filesystem>

#include "hlt/core/checkpoint.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

// A small regression problem: the same network twice, trained by the two optimizers.
struct Problem {
  torch::nn::Sequential net;
  torch::Tensor x, y;
  explicit Problem(uint64_t seed) {
    torch::manual_seed(seed);
    net = torch::nn::Sequential(torch::nn::Linear(3, 9), torch::nn::Functional(torch::tanh),
                                torch::nn::Linear(9, 2));
    x = torch::randn({16, 3});
    y = torch::randn({16, 2});
  }
  torch::Tensor loss() { return (net->forward(x) - y).square().mean(); }
};

TEST(FlatAdam, FollowsTorchAdam) {
  Problem a(5), b(5);
  torch::optim::Adam reference(a.net->parameters(), torch::optim::AdamOptions(0.01));
  FlatAdam flat(b.net->parameters(), FlatAdamOptions{0.01});
  EXPECT_EQ(flat.size(), 3 * 9 + 9 + 9 * 2 + 2);
  for (int step = 0; step < 50; ++step) {
    reference.zero_grad();
    a.loss().backward();
    reference.step();
    flat.zero_grad();
    b.loss().backward();
    flat.step();
  }
  EXPECT_EQ(flat.steps(), 50);
  const auto pa = a.net->parameters(), pb = b.net->parameters();
  for (size_t i = 0; i < pa.size(); ++i)
    EXPECT_TRUE(torch::allclose(pa[i], pb[i], 1e-4, 1e-6)) << i << "\n" << pa[i] - pb[i];
  // It did train: the loss fell.
  EXPECT_LT(b.loss().item<double>(), 0.9 * Problem(5).loss().item<double>());
}

// `n` steps of `opt` on `p`'s loss.
void train(FlatAdam& opt, Problem& p, int n) {
  for (int step = 0; step < n; ++step) {
    opt.zero_grad();
    p.loss().backward();
    opt.step();
  }
}

// After restart() the optimizer steps as a new one built on the current parameters does: 20 steps of one,
// restart, 20 more, against 20 steps of one, then a fresh one (rebinding the parameters) for 20 more.
TEST(FlatAdam, RestartStepsAsAFreshOptimizer) {
  Problem a(7), b(7);
  FlatAdam first(a.net->parameters(), FlatAdamOptions{0.01});
  FlatAdam flat(b.net->parameters(), FlatAdamOptions{0.01});
  train(first, a, 20);
  train(flat, b, 20);
  flat.restart();
  EXPECT_EQ(flat.steps(), 0);
  FlatAdam fresh(a.net->parameters(), FlatAdamOptions{0.01});
  train(fresh, a, 20);
  train(flat, b, 20);
  const auto pa = a.net->parameters(), pb = b.net->parameters();
  for (size_t i = 0; i < pa.size(); ++i)
    EXPECT_TRUE(torch::equal(pa[i], pb[i])) << i << "\n" << pa[i] - pb[i];
  // Without the restart the second half differs (the moments of the first 20 steps scale it).
  Problem c(7);
  FlatAdam kept(c.net->parameters(), FlatAdamOptions{0.01});
  train(kept, c, 40);
  EXPECT_FALSE(torch::allclose(c.net->parameters()[0], pb[0], 1e-4, 1e-6));
}

TEST(FlatAdam, ParametersAndGradientsAreViewsOfTheFlatBuffers) {
  Problem p(1);
  const auto before = torch::cat({p.net->parameters()[0].flatten(), p.net->parameters()[1].flatten()});
  FlatAdam flat(p.net->parameters(), FlatAdamOptions{0.01});
  // Values kept, storage shared.
  EXPECT_TRUE(torch::equal(flat.flat_parameters().narrow(0, 0, before.numel()), before));
  flat.zero_grad();
  p.loss().backward();
  auto w = p.net->parameters()[0];
  EXPECT_EQ(w.grad().data_ptr<float>(), flat.flat_gradients().data_ptr<float>());
  EXPECT_GT(flat.flat_gradients().abs().sum().item<double>(), 0.0);
  // Gradients accumulate until zeroed.
  const auto once = flat.flat_gradients().clone();
  p.loss().backward();
  EXPECT_TRUE(torch::allclose(flat.flat_gradients(), 2 * once));
  flat.zero_grad();
  EXPECT_EQ(flat.flat_gradients().abs().sum().item<double>(), 0.0);
  // A step moves the module's own parameters.
  p.loss().backward();
  const auto w0 = w.detach().clone();
  flat.step();
  EXPECT_FALSE(torch::equal(w.detach(), w0));
}

TEST(FlatAdam, CheckpointRoundTripContinuesIdentically) {
  const std::string path = (std::filesystem::temp_directory_path() / "hlt_flat_adam.pt").string();
  Problem a(3);
  FlatAdam opt(a.net->parameters(), FlatAdamOptions{0.02});
  for (int i = 0; i < 5; ++i) {
    opt.zero_grad();
    a.loss().backward();
    opt.step();
  }
  {
    CheckpointWriter w;
    w.add_module("net", *a.net);
    opt.save(w, "net");
    w.save(path);
  }
  Problem b(4);  // other weights, replaced by the checkpoint's; the same data
  b.x = a.x;
  b.y = a.y;
  FlatAdam other(b.net->parameters(), FlatAdamOptions{0.02});
  CheckpointReader r(path);
  r.load_module("net", *b.net);
  other.load(r, "net");
  EXPECT_EQ(other.steps(), 5);
  for (int i = 0; i < 3; ++i) {
    for (auto* pair : {&opt, &other}) {
      Problem& p = pair == &opt ? a : b;
      pair->zero_grad();
      p.loss().backward();
      pair->step();
    }
  }
  EXPECT_TRUE(torch::equal(opt.flat_parameters(), other.flat_parameters()));
  // Moments of another size are refused by name.
  torch::nn::Linear small(2, 2);
  FlatAdam wrong(small->parameters(), FlatAdamOptions{});
  EXPECT_THROW(wrong.load(r, "net"), Error);
}

}  // namespace
}  // namespace hlt
