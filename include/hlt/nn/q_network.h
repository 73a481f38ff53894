// hlt::QNetwork: a soft Q-function Q(s, a) = MLP([s, a]) with ReLU hidden layers (SAC's critic, 2 x 256).
#pragma once

#include <cstdint>
#include <vector>

#include <torch/nn/module.h>
#include <torch/nn/modules/container/modulelist.h>

namespace hlt {

struct QNetworkOptions {
  int64_t state_dim = 0;
  int64_t action_dim = 0;
  std::vector<int64_t> hidden = {256, 256};
};

class QNetworkImpl : public torch::nn::Module {
 public:
  explicit QNetworkImpl(const QNetworkOptions& options);
  // Q-values, [B, 1].
  torch::Tensor forward(const torch::Tensor& state, const torch::Tensor& action);
  const QNetworkOptions& options() const { return options_; }
  torch::nn::ModuleList layers{nullptr};

 private:
  QNetworkOptions options_;
};
TORCH_MODULE(QNetwork);

}  // namespace hlt
