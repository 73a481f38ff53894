#include "hlt/nn/q_network.h"

#include <torch/torch.h>

#include "hlt/util/error.h"

namespace hlt {

QNetworkImpl::QNetworkImpl(const QNetworkOptions& o) : options_(o) {
  check(o.state_dim > 0 && o.action_dim > 0 && !o.hidden.empty(),
        "QNetwork needs positive sizes and a hidden layer");
  layers = register_module("layers", torch::nn::ModuleList());
  int64_t width = o.state_dim + o.action_dim;
  for (int64_t h : o.hidden) {
    layers->push_back(torch::nn::Linear(width, h));
    width = h;
  }
  layers->push_back(torch::nn::Linear(width, 1));
}

torch::Tensor QNetworkImpl::forward(const torch::Tensor& state, const torch::Tensor& action) {
  torch::Tensor x = torch::cat({state, action}, -1);
  const size_t n = layers->size();
  for (size_t i = 0; i < n; ++i) {
    x = layers[i]->as<torch::nn::Linear>()->forward(x);
    if (i + 1 < n) x = torch::relu(x);
  }
  return x;
}

}  // namespace hlt
