// The activations over raw values against ATen's: values, gradients, and ReLU's NaN and -0.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>
#include <limits>

#include "hlt/nn/activation.h"

namespace hlt {
namespace {

template <typename T>
void check_against_aten(torch::Dtype dtype, double tolerance) {
  torch::manual_seed(5);
  const int64_t n = 67;  // not a multiple of any vector width
  const torch::Tensor x = torch::randn({n}, dtype) * 4;
  const torch::Tensor g = torch::randn({n}, dtype);
  for (Activation a : {Activation::kSin, Activation::kRelu}) {
    SCOPED_TRACE(activation_name(a));
    torch::Tensor y = torch::empty_like(x), grad = g.clone(), scratch = torch::empty_like(x);
    activate_values(x.data_ptr<T>(), y.data_ptr<T>(), n, a);
    EXPECT_LE((y - activate(x, a)).abs().max().item<double>(), tolerance);
    activation_gradient(grad.data_ptr<T>(), x.data_ptr<T>(), y.data_ptr<T>(), scratch.data_ptr<T>(), n, a);
    const torch::Tensor expected = a == Activation::kSin ? g * torch::cos(x) : g * (x > 0).to(dtype);
    EXPECT_LE((grad - expected).abs().max().item<double>(), tolerance);
  }
}

TEST(Activation, RawValuesMatchAtenInFloatAndDouble) {
  check_against_aten<float>(torch::kFloat32, 1e-6);
  check_against_aten<double>(torch::kFloat64, 1e-15);
}

TEST(Activation, ReluKeepsNanAndNegativeZeroAsAtenDoes) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const torch::Tensor x = torch::tensor({-0.0f, -1.0f, nan, 2.0f});
  torch::Tensor y = torch::empty_like(x), ours = torch::empty_like(x);
  at::clamp_min_out(y, x, 0);
  activate_values(x.data_ptr<float>(), ours.data_ptr<float>(), 4, Activation::kRelu);
  for (int i = 0; i < 4; ++i) {
    const float a = ours[i].item<float>(), b = y[i].item<float>();
    EXPECT_TRUE((std::isnan(a) && std::isnan(b)) || (a == b && std::signbit(a) == std::signbit(b))) << i;
  }
  // The tensor form takes the same path.
  torch::Tensor out = torch::empty_like(x);
  activate_out(out, x, Activation::kRelu);
  EXPECT_TRUE(std::isnan(out[2].item<float>()));
  EXPECT_TRUE(std::signbit(out[0].item<float>()));
}

}  // namespace
}  // namespace hlt
