#include "hlt/nn/reward_model.h"

#include <torch/torch.h>

#include "hlt/util/error.h"

namespace hlt {

RewardModelImpl::RewardModelImpl(const RewardModelOptions& o) : options_(o) {
  check(o.state_dim > 0 && o.action_dim > 0 && o.hidden > 0,
        "RewardModel needs positive sizes, got n={} m={} h={}", o.state_dim, o.action_dim, o.hidden);
  fc1 = register_module("fc1", torch::nn::Linear(o.state_dim + o.action_dim, o.hidden));
  fc2 = register_module("fc2", torch::nn::Linear(o.hidden, o.hidden));
  fc3 = register_module("fc3", torch::nn::Linear(o.hidden, 1));
}

torch::Tensor RewardModelImpl::forward(const torch::Tensor& state, const torch::Tensor& action) {
  torch::Tensor h = torch::relu(fc1(torch::cat({state, action}, -1)));
  h = torch::relu(fc2(h));
  return fc3(h);
}

torch::Tensor RewardModelImpl::td_loss(const torch::Tensor& state, const torch::Tensor& action,
                                       const torch::Tensor& reward, const torch::Tensor& next_state,
                                       const torch::Tensor& next_action, const torch::Tensor& done,
                                       double gamma) {
  torch::Tensor target;
  if (gamma == 0.0) {
    target = reward;
  } else {
    torch::NoGradGuard no_grad;
    target = reward + gamma * (1.0 - done) * forward(next_state, next_action);
  }
  return (target.detach() - forward(state, action)).square().mean();
}

}  // namespace hlt
