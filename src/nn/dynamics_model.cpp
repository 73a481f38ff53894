#include "hlt/nn/dynamics_model.h"

#include <cmath>

#include <torch/torch.h>

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

}  // namespace hlt
