#include "hlt/nn/reward_model.h"

#include <torch/torch.h>

#include "hlt/nn/batched_forward.h"
#include "hlt/nn/dense_layers.h"
#include "hlt/util/error.h"

namespace hlt {

RewardModelImpl::RewardModelImpl(const RewardModelOptions& o) : options_(o) {
  check(o.state_dim > 0 && o.action_dim > 0 && o.hidden > 0,
        "RewardModel needs positive sizes, got n={} m={} h={}", o.state_dim, o.action_dim, o.hidden);
  normaliser_ = InputNormaliser(o.state_dim, o.input_offset, o.input_scale, o.input_reference, "RewardModel");
  fc1 = register_module("fc1", torch::nn::Linear(o.state_dim + o.action_dim, o.hidden));
  fc2 = register_module("fc2", torch::nn::Linear(o.hidden, o.hidden));
  fc3 = register_module("fc3", torch::nn::Linear(o.hidden, 1));
}

torch::Tensor RewardModelImpl::forward(const torch::Tensor& state, const torch::Tensor& action) {
  torch::Tensor h = torch::relu(fc1(torch::cat({normaliser_.apply(state), action}, -1)));
  h = torch::relu(fc2(h));
  return fc3(h);
}

DenseChain RewardModelImpl::chain() const {
  return DenseChain{{normaliser_.enabled() ? normaliser_.fold_into(fc1) : fc1, fc2, fc3}, Activation::kRelu};
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
  // The hidden layers' products go through BLAS (ATen's out= kernels); the one-output last layer, the
  // ReLUs, the target and the bias gradients run as Eigen expressions over the same buffers.
  c10::InferenceMode guard;  // its buffers are only ever touched in inference mode
  const int64_t batch = state.size(0), n = options_.state_dim, m = options_.action_dim, h = options_.hidden;
  for (const torch::Tensor* t : {&state, &action, &reward, &next_state, &next_action, &done})
    check(t->is_contiguous() && t->scalar_type() == fc1->weight.scalar_type(),
          "RewardModel::td_loss_with_gradient needs contiguous inputs of the model's dtype");
  match_buffers({&x_, &h1_, &h2_, &r_, &next_x_, &next_h1_, &next_h2_, &next_r_, &g_r_, &g_h2_, &g_h1_},
                fc1->weight);
  double loss = 0;
  dispatch_floating(x_, [&](auto tag) {
    using T = decltype(tag);
    using Vec = Eigen::Matrix<T, Eigen::Dynamic, 1>;
    using Row = Eigen::Matrix<T, 1, Eigen::Dynamic>;
    const Eigen::Map<const Row> w3(fc3->weight.data_ptr<T>(), h);
    const T b3 = fc3->bias.data_ptr<T>()[0];
    // r(s, a) for a batch, keeping the activations.
    const auto pass = [&](const torch::Tensor& s, const torch::Tensor& a, torch::Tensor& x, torch::Tensor& h1,
                          torch::Tensor& h2, torch::Tensor& out) {
      auto xm = row_map<T>(sized(x, {batch, n + m}));
      xm.leftCols(n) = row_map<T>(s);
      xm.rightCols(m) = row_map<T>(a);
      normaliser_.apply_in_place(x);
      dense_forward(h1, x, fc1->weight, fc1->bias);
      row_map<T>(h1) = row_map<T>(h1).cwiseMax(T(0));
      dense_forward(h2, h1, fc2->weight, fc2->bias);
      row_map<T>(h2) = row_map<T>(h2).cwiseMax(T(0));
      Eigen::Map<Vec>(sized(out, {batch}).template data_ptr<T>(), batch) =
          (row_map<T>(h2) * w3.transpose()).array() + b3;
    };
    const Eigen::Map<const Vec> r(reward.data_ptr<T>(), batch), d(done.data_ptr<T>(), batch);
    pass(state, action, x_, h1_, h2_, r_);
    Vec diff = -Eigen::Map<const Vec>(r_.data_ptr<T>(), batch);
    diff += r;
    if (gamma != 0.0) {
      pass(next_state, next_action, next_x_, next_h1_, next_h2_, next_r_);
      diff.array() +=
          T(gamma) * (T(1) - d.array()) * Eigen::Map<const Vec>(next_r_.data_ptr<T>(), batch).array();
    }
    // loss = mean(diff^2) with diff = target - r(s, a); d loss / d r = -2 diff / B.
    loss = static_cast<double>(diff.squaredNorm()) / static_cast<double>(batch);
    const Vec g_r = diff * T(-2.0 * scale / static_cast<double>(batch));
    Eigen::Map<Row>(gradient_of(fc3->weight).template data_ptr<T>(), h) = g_r.transpose() * row_map<T>(h2_);
    gradient_of(fc3->bias).template data_ptr<T>()[0] = g_r.sum();
    auto g2 = row_map<T>(sized(g_h2_, {batch, h}));
    g2.noalias() = g_r * w3;
    relu_gradient_of(h2_, g_h2_);
    sum_rows_into(g2, Eigen::Map<Row>(gradient_of(fc2->bias).template data_ptr<T>(), h));
  });
  at::mm_out(gradient_of(fc2->weight), g_h2_.t(), h1_);
  at::mm_out(g_h1_, g_h2_, fc2->weight);
  dispatch_floating(x_, [&](auto tag) {
    using T = decltype(tag);
    auto g1 = row_map<T>(g_h1_);
    relu_gradient_of(h1_, g_h1_);
    sum_rows_into(g1, Eigen::Map<Eigen::Matrix<T, 1, Eigen::Dynamic>>(
                          gradient_of(fc1->bias).template data_ptr<T>(), h));
  });
  at::mm_out(gradient_of(fc1->weight), g_h1_.t(), x_);
  return loss;
}

}  // namespace hlt
