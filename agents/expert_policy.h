// hlt::ExpertPolicy: a fixed policy given as plain-text weights of a ReLU MLP (the format of
// agents/experts/README.md, e.g. PyBullet's pretrained Ant policy), acting deterministically with its output
// clipped to [-1, 1]. The demonstrator for imitation learning; tools accept it as "expert:PATH".
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "envs/rollout.h"

namespace hlt {

class ExpertPolicy : public PolicySource {
 public:
  // Throws hlt::Error naming the file and line for a missing, truncated or malformed file, layers whose
  // shapes do not chain, or non-finite numbers.
  explicit ExpertPolicy(const std::string& path);

  std::string describe() const override;
  // Precondition: observation.size() == observation_dim() (checked).
  Eigen::VectorXd act(const Eigen::VectorXd& observation) override;

  int observation_dim() const { return static_cast<int>(weights_.front().rows()); }
  int action_dim() const { return static_cast<int>(weights_.back().cols()); }

  static constexpr const char* kPrefix = "expert:";

 private:
  std::string path_;
  std::vector<Eigen::MatrixXd> weights_;  // layer l: [in, out]
  std::vector<Eigen::RowVectorXd> biases_;
};

}  // namespace hlt
