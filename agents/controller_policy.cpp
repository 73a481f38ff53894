#include "agents/controller_policy.h"

#include <torch/torch.h>

namespace hlt {

at::Tensor observation_tensor(const Eigen::VectorXd& v) {
  return torch::from_blob(const_cast<double*>(v.data()), {v.size()}, torch::kFloat64).to(torch::kFloat32);
}

Eigen::VectorXd action_vector(const at::Tensor& t) {
  const at::Tensor d = t.to(torch::kFloat64).contiguous();
  return Eigen::Map<const Eigen::VectorXd>(d.data_ptr<double>(), d.numel());
}

ControllerPolicy::ControllerPolicy(Controller& controller, std::function<void(Controller&)> before_act)
    : controller_(controller), before_act_(std::move(before_act)) {}

std::string ControllerPolicy::describe() const {
  return "controller " + controller_.name();
}

void ControllerPolicy::reset() {
  controller_.reset();
}

Eigen::VectorXd ControllerPolicy::act(const Eigen::VectorXd& observation) {
  if (before_act_) before_act_(controller_);
  return action_vector(controller_.act(observation_tensor(observation)));
}

}  // namespace hlt
