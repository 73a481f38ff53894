// Finite-difference helpers shared by every gradient test: central differences of a scalar function of a
// tensor, compared with what autograd (or an analytic formula) says. Use double precision.
#pragma once

#include <functional>

#include <gtest/gtest.h>
#include <torch/torch.h>

namespace hlt::testing {

// d f / d x by central differences, same shape as x. f must not modify x.
inline torch::Tensor finite_difference_gradient(const std::function<torch::Tensor(const torch::Tensor&)>& f,
                                                const torch::Tensor& x, double eps = 1e-6) {
  torch::NoGradGuard no_grad;
  torch::Tensor xd = x.detach().clone().to(torch::kFloat64);
  torch::Tensor grad = torch::zeros_like(xd);
  auto flat = xd.view({-1});
  auto g = grad.view({-1});
  for (int64_t i = 0; i < flat.numel(); ++i) {
    const double orig = flat[i].item<double>();
    flat[i] = orig + eps;
    const double up = f(xd).item<double>();
    flat[i] = orig - eps;
    const double down = f(xd).item<double>();
    flat[i] = orig;
    g[i] = (up - down) / (2 * eps);
  }
  return grad;
}

// Relative error max|a - b| / max(max|b|, floor).
inline double relative_error(const torch::Tensor& a, const torch::Tensor& b, double floor = 1e-8) {
  const double diff = (a - b).abs().max().item<double>();
  const double scale = std::max(b.abs().max().item<double>(), floor);
  return diff / scale;
}

// Checks the autograd gradient of f at x against central differences.
inline void expect_gradient_matches(const std::function<torch::Tensor(const torch::Tensor&)>& f,
                                    const torch::Tensor& x, double tolerance = 1e-6) {
  torch::Tensor xg = x.detach().clone().to(torch::kFloat64).requires_grad_(true);
  torch::Tensor y = f(xg);
  auto grads = torch::autograd::grad({y}, {xg});
  torch::Tensor fd = finite_difference_gradient(f, x);
  EXPECT_LT(relative_error(grads[0], fd), tolerance) << "autograd:\n"
                                                     << grads[0] << "\nfinite differences:\n"
                                                     << fd;
}

}  // namespace hlt::testing
