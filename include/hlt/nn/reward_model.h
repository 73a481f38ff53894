// hlt::RewardModel: the learned reward r(s, a) = Linear(n+m, 200) ReLU Linear(200, 200) ReLU Linear(200, 1)
// on [x(s), a] (x(s) = s unless the options ask for input normalisation),
// trained by a TD-style loss so that it also carries value information for rewards that depend on more
// than the current state (paper appendix, "Models"). With `reads_next_state` the same network is r(s', a),
// the reward of the state the step reaches (see RewardModelOptions).
#pragma once

#include <cstdint>
#include <vector>

#include <torch/nn/module.h>

#include <torch/nn/modules/linear.h>
#include "hlt/nn/dense_chain.h"
#include "hlt/nn/dense_layers.h"
#include "hlt/nn/input_normalisation.h"

namespace hlt {

struct RewardModelOptions {
  int64_t state_dim = 0;
  int64_t action_dim = 0;
  int64_t hidden = 200;
  // Input normalisation of the state (as GaussianPolicyOptions'; all empty: none).
  std::vector<double> input_offset, input_scale;
  std::vector<int64_t> input_reference;
  // Reads the state a step reaches instead of the one it starts from: r(s', a) rather than r(s, a). Why: the
  // robot tasks' rewards are functions of the observation a step returns (block stacking's stages switch at
  // the grasp), so r(s, a) has to predict the transition as well, where r(s', a) is the task's reward
  // function itself and the dynamics model supplies s'. Trained by plain regression (its TD target would
  // need the state after s'); the deterministic hybrid's adjoint assumes r(s, a) and refuses it.
  bool reads_next_state = false;
};

class RewardModelImpl : public torch::nn::Module {
 public:
  explicit RewardModelImpl(const RewardModelOptions& options);

  // Predicted reward, [B, 1], of the network's input state (see reads_next_state).
  torch::Tensor forward(const torch::Tensor& state, const torch::Tensor& action);
  // The predicted reward of the step (state, action) -> next_state: forward(next_state, action) if the
  // model reads the next state, else forward(state, action).
  torch::Tensor predict(const torch::Tensor& state, const torch::Tensor& action,
                        const torch::Tensor& next_state) {
    return forward(options_.reads_next_state ? next_state : state, action);
  }
  // The network as one autograd node: dense_chain(chain(), {state, action}) equals forward().
  DenseChain chain() const;
  // mean((r + gamma (1 - done) r(s', a')).detach() - r(s, a))^2; reward and done are [B, 1].
  torch::Tensor td_loss(const torch::Tensor& state, const torch::Tensor& action, const torch::Tensor& reward,
                        const torch::Tensor& next_state, const torch::Tensor& next_action,
                        const torch::Tensor& done, double gamma);
  // The same loss's value, with `scale` times its gradient written (not accumulated) into the parameters'
  // .grad() tensors by a hand-written backward pass (tested against autograd) instead of a graph.
  double td_loss_with_gradient(const torch::Tensor& state, const torch::Tensor& action,
                               const torch::Tensor& reward, const torch::Tensor& next_state,
                               const torch::Tensor& next_action, const torch::Tensor& done, double gamma,
                               double scale = 1.0);

  const RewardModelOptions& options() const { return options_; }
  const InputNormaliser& normaliser() const { return normaliser_; }
  torch::nn::Linear fc1{nullptr}, fc2{nullptr}, fc3{nullptr};

 private:
  RewardModelOptions options_;
  InputNormaliser normaliser_;
  // td_loss_with_gradient's buffers, kept between calls.
  torch::Tensor x_ = empty_buffer(), h1_ = empty_buffer(), h2_ = empty_buffer(), r_ = empty_buffer(),
                next_x_ = empty_buffer(), next_h1_ = empty_buffer(), next_h2_ = empty_buffer(),
                next_r_ = empty_buffer(), target_ = empty_buffer(), g_r_ = empty_buffer(),
                g_h2_ = empty_buffer(), g_h1_ = empty_buffer();
};
TORCH_MODULE(RewardModel);

}  // namespace hlt
