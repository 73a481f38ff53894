#include "hlt/nn/twin_q_network.h"

#include <torch/torch.h>

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

}  // namespace hlt
