// hlt::ControllerPolicy: a Controller (which plans on tensors) seen as a PolicySource (which maps Eigen
// observations to actions), so that training's evaluations and the tools run one episode loop
// (run_episode in envs/rollout.h). Also the two conversions between the environments' Eigen vectors and
// the networks' float tensors.
#pragma once

#include <functional>
#include <string>

#include <ATen/core/Tensor.h>

#include "envs/rollout.h"
#include "hlt/control/controller.h"

namespace hlt {

// An observation as a float32 tensor [n] for a controller.
at::Tensor observation_tensor(const Eigen::VectorXd& observation);
// A controller's action as a double vector [m] for an environment.
Eigen::VectorXd action_vector(const at::Tensor& action);

class ControllerPolicy : public PolicySource {
 public:
  // `controller` must outlive this. `before_act`, if set, runs before every action (the trainer tells the
  // deterministic hybrid how many interactions there have been).
  explicit ControllerPolicy(Controller& controller, std::function<void(Controller&)> before_act = {});
  std::string describe() const override;
  // Resets the controller's warm start (call at each episode start).
  void reset();
  Eigen::VectorXd act(const Eigen::VectorXd& observation) override;

 private:
  Controller& controller_;
  std::function<void(Controller&)> before_act_;
};

}  // namespace hlt
