#include "hlt/nn/reward_model.h"

#include <torch/torch.h>

#include "hlt/nn/dense_layers.h"
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

double RewardModelImpl::td_loss_with_gradient(const torch::Tensor& state, const torch::Tensor& action,
                                              const torch::Tensor& reward, const torch::Tensor& next_state,
                                              const torch::Tensor& next_action, const torch::Tensor& done,
                                              double gamma, double scale) {
  torch::NoGradGuard no_grad;
  match_buffers({&x_, &h1_, &h2_, &r_, &next_x_, &next_h1_, &next_h2_, &next_r_, &g_r_, &g_h2_, &g_h1_},
                fc1->weight);
  const auto pass = [this](const torch::Tensor& s, const torch::Tensor& a, torch::Tensor& x,
                           torch::Tensor& h1, torch::Tensor& h2, torch::Tensor& out) {
    at::cat_out(x, {s, a}, 1);
    dense_forward(h1, x, fc1->weight, fc1->bias);
    h1.clamp_min_(0);
    dense_forward(h2, h1, fc2->weight, fc2->bias);
    h2.clamp_min_(0);
    dense_forward(out, h2, fc3->weight, fc3->bias);
  };
  if (gamma == 0.0) {
    target_ = reward;
  } else {
    pass(next_state, next_action, next_x_, next_h1_, next_h2_, next_r_);
    target_ = reward + gamma * (1.0 - done) * next_r_;
  }
  pass(state, action, x_, h1_, h2_, r_);
  // d loss / d r = -2 (target - r) / B.
  at::sub_out(g_r_, target_, r_);
  const double loss = g_r_.square().mean().item<double>();
  g_r_.mul_(-2.0 * scale / static_cast<double>(state.size(0)));
  dense_backward(g_r_, h2_, fc3->weight, gradient_of(fc3->weight), gradient_of(fc3->bias), &g_h2_);
  at::threshold_backward_out(g_h2_, g_h2_, h2_, 0.0);
  dense_backward(g_h2_, h1_, fc2->weight, gradient_of(fc2->weight), gradient_of(fc2->bias), &g_h1_);
  at::threshold_backward_out(g_h1_, g_h1_, h1_, 0.0);
  dense_backward(g_h1_, x_, fc1->weight, gradient_of(fc1->weight), gradient_of(fc1->bias), nullptr);
  return loss;
}

}  // namespace hlt
