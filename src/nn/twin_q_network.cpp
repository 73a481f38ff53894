#include "hlt/nn/twin_q_network.h"

#include <torch/torch.h>

#include "hlt/nn/dense_layers.h"
#include "hlt/util/error.h"

namespace hlt {

TwinQNetworkImpl::TwinQNetworkImpl(const TwinQNetworkOptions& o) : options_(o) {
  check(o.state_dim > 0 && o.action_dim > 0 && !o.hidden.empty(),
        "TwinQNetwork needs positive sizes and a hidden layer");
  std::vector<int64_t> widths{o.state_dim + o.action_dim};
  widths.insert(widths.end(), o.hidden.begin(), o.hidden.end());
  widths.push_back(1);
  const size_t layers = widths.size() - 1;
  std::vector<std::vector<torch::Tensor>> w(layers), b(layers);
  for (int critic = 0; critic < 2; ++critic) {
    for (size_t l = 0; l < layers; ++l) {
      torch::nn::Linear init(widths[l], widths[l + 1]);
      w[l].push_back(init->weight.detach().t());
      b[l].push_back(init->bias.detach().unsqueeze(0));
    }
  }
  for (size_t l = 0; l < layers; ++l) {
    weights.push_back(register_parameter("weight" + std::to_string(l), torch::stack(w[l]).contiguous()));
    biases.push_back(register_parameter("bias" + std::to_string(l), torch::stack(b[l]).contiguous()));
  }
}

torch::Tensor TwinQNetworkImpl::forward(const torch::Tensor& state, const torch::Tensor& action) {
  const torch::Tensor sa = torch::cat({state, action}, -1);
  torch::Tensor x = sa.unsqueeze(0).expand({2, sa.size(0), sa.size(1)});
  for (size_t l = 0; l < weights.size(); ++l) {
    x = torch::baddbmm(biases[l], x, weights[l]);
    if (l + 1 < weights.size()) x = torch::relu(x);
  }
  return x;
}

torch::Tensor TwinQNetworkImpl::min_q(const torch::Tensor& state, const torch::Tensor& action) {
  const torch::Tensor q = forward(state, action);
  return torch::min(q[0], q[1]);
}

const torch::Tensor& TwinQNetworkImpl::forward_keep(const torch::Tensor& state, const torch::Tensor& action) {
  c10::InferenceMode guard;  // its buffers are only ever touched in inference mode
  at::cat_out(input_, {state, action}, 1);
  const size_t layers = weights.size();
  while (outputs_.size() < layers) {
    outputs_.push_back(empty_buffer());
    grads_.push_back(empty_buffer());
  }
  torch::Tensor x = input_.unsqueeze(0).expand({2, input_.size(0), input_.size(1)});
  for (size_t l = 0; l < layers; ++l) {
    at::baddbmm_out(outputs_[l], biases[l], l == 0 ? x : outputs_[l - 1], weights[l]);
    if (l + 1 < layers) outputs_[l].clamp_min_(0);
  }
  return outputs_.back();
}

void TwinQNetworkImpl::backward_parameters(const torch::Tensor& grad_q) {
  c10::InferenceMode guard;  // its buffers are only ever touched in inference mode
  const torch::Tensor x = input_.unsqueeze(0).expand({2, input_.size(0), input_.size(1)});
  torch::Tensor g = grad_q;
  for (size_t l = weights.size(); l-- > 0;) {
    const torch::Tensor& in = l == 0 ? x : outputs_[l - 1];
    at::bmm_out(gradient_of(weights[l]), in.transpose(1, 2), g);
    at::sum_out(gradient_of(biases[l]), g, {1}, /*keepdim=*/true);
    if (l == 0) break;
    at::bmm_out(grads_[l - 1], g, weights[l].transpose(1, 2));
    at::threshold_backward_out(grads_[l - 1], grads_[l - 1], outputs_[l - 1], 0.0);
    g = grads_[l - 1];
  }
}

torch::Tensor TwinQNetworkImpl::backward_action(const torch::Tensor& grad_q) {
  c10::InferenceMode guard;  // its buffers are only ever touched in inference mode
  torch::Tensor g = grad_q;
  for (size_t l = weights.size(); l-- > 1;) {
    at::bmm_out(grads_[l - 1], g, weights[l].transpose(1, 2));
    at::threshold_backward_out(grads_[l - 1], grads_[l - 1], outputs_[l - 1], 0.0);
    g = grads_[l - 1];
  }
  // Only the action's columns of the first layer's input gradient are needed.
  const int64_t n = options_.state_dim;
  const torch::Tensor w_action = weights[0].narrow(1, n, options_.action_dim);  // [2, m, h]
  return at::bmm(g, w_action.transpose(1, 2)).sum(0);
}

}  // namespace hlt
