#include "hlt/nn/dynamics_model.h"

#include <cmath>

#include <torch/torch.h>

#include "hlt/nn/dense_layers.h"
#include "hlt/util/error.h"

namespace hlt {

DynamicsModelImpl::DynamicsModelImpl(const DynamicsModelOptions& o) : options_(o) {
  check(o.state_dim > 0 && o.action_dim > 0 && o.hidden > 0,
        "DynamicsModel needs positive sizes, got n={} m={} h={}", o.state_dim, o.action_dim, o.hidden);
  fc1 = register_module("fc1", torch::nn::Linear(o.state_dim + o.action_dim, o.hidden));
  fc2 = register_module("fc2", torch::nn::Linear(o.hidden, o.state_dim));
  log_std_param = register_parameter("log_std", torch::zeros({1, o.state_dim}));
}

torch::Tensor DynamicsModelImpl::forward(const torch::Tensor& state, const torch::Tensor& action) {
  torch::Tensor h = fc1(torch::cat({state, action}, -1));
  return state + fc2(activate(h, options_.activation));
}

torch::Tensor DynamicsModelImpl::log_std() const {
  return log_std_param.clamp(options_.log_std_min, options_.log_std_max);
}

torch::Tensor DynamicsModelImpl::loss(const torch::Tensor& state, const torch::Tensor& action,
                                      const torch::Tensor& next_state) {
  const torch::Tensor mean = forward(state, action);
  const torch::Tensor ls = log_std();
  // log N(x; mu, sigma) = -(x - mu)^2 / (2 sigma^2) - log sigma - log(2 pi) / 2
  const torch::Tensor z = (next_state - mean) * torch::exp(-ls);
  const torch::Tensor log_density = -0.5 * z.square() - ls - 0.5 * std::log(2.0 * M_PI);
  return -log_density.mean();
}

double DynamicsModelImpl::loss_with_gradient(const torch::Tensor& state, const torch::Tensor& action,
                                             const torch::Tensor& next_state, double scale) {
  torch::NoGradGuard no_grad;
  const int64_t batch = state.size(0), n = options_.state_dim;
  match_buffers({&x_, &h_, &act_, &mean_, &z_, &g_mean_, &g_act_, &cos_}, fc1->weight);
  at::cat_out(x_, {state, action}, 1);
  dense_forward(h_, x_, fc1->weight, fc1->bias);
  activate_out(act_, h_, options_.activation);
  dense_forward(mean_, act_, fc2->weight, fc2->bias);
  mean_.add_(state);
  const torch::Tensor ls = log_std();
  const torch::Tensor inv_std = torch::exp(-ls);
  at::sub_out(z_, next_state, mean_);
  z_.mul_(inv_std);
  // loss = mean(z^2) / 2 + mean(log_std) + log(2 pi) / 2 over the B x n entries.
  const torch::Tensor z_sq_col = z_.square().sum(0, /*keepdim=*/true);  // [1, n]
  const double count = static_cast<double>(batch * n);
  const double loss = (0.5 * z_sq_col.sum() / count + ls.mean()).item<double>() + 0.5 * std::log(2.0 * M_PI);

  // d loss / d mean = -z / (sigma B n); d loss / d log_std_j = 1 / n - sum_b z_bj^2 / (B n), zero where
  // the clamp is active (as autograd's clamp backward).
  at::mul_out(g_mean_, z_, inv_std);
  g_mean_.mul_(-scale / count);
  dense_backward(g_mean_, act_, fc2->weight, gradient_of(fc2->weight), gradient_of(fc2->bias), &g_act_);
  activation_backward_(g_act_, h_, act_, options_.activation, cos_);
  dense_backward(g_act_, x_, fc1->weight, gradient_of(fc1->weight), gradient_of(fc1->bias), nullptr);
  const torch::Tensor inside =
      (log_std_param >= options_.log_std_min).logical_and(log_std_param <= options_.log_std_max);
  gradient_of(log_std_param)
      .copy_(((1.0 / n - z_sq_col / count) * scale).masked_fill_(inside.logical_not(), 0.0));
  return loss;
}

}  // namespace hlt
