// hlt::Demonstrations: recorded episodes of a policy on an environment (each step's observation, the
// demonstrator's action, the reward and what followed): the dataset of imitation learning (paper Alg. 3),
// and its file format.
//
// File format `.hltd`, version 1: text header lines
//   hlt-demonstrations 1 / env NAME / observation_dim N / action_dim M / frame_skip K / source TEXT /
//   episodes E / transitions T / data
// (one per line), then T rows of 3 + 2N + M + 2 little-endian float64 numbers
//   episode, step, observation[N], action[M], reward, next_observation[N], terminated, truncated,
// episodes in order and steps consecutive from 0, then the checksum trailer of hlt/util/checksum.h.
// Written atomically; a truncated, corrupt, mismatched or malformed file is an hlt::Error naming what is
// wrong.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace hlt {

struct DemoStep {
  Eigen::VectorXd observation, action, next_observation;
  double reward = 0;
  bool terminated = false, truncated = false;
};

class Demonstrations {
 public:
  Demonstrations(std::string env, int observation_dim, int action_dim, int frame_skip, std::string source);

  // Appends one episode. Precondition: every step has the declared sizes and finite numbers (checked).
  void add_episode(std::vector<DemoStep> steps);

  void save(const std::string& path) const;
  static Demonstrations load(const std::string& path);
  // Throws unless the demonstrations were recorded on `env` with these sizes and frame skip.
  void check_matches(const std::string& env, int observation_dim, int action_dim, int frame_skip) const;

  const std::string& env() const { return env_; }
  int observation_dim() const { return n_; }
  int action_dim() const { return m_; }
  int frame_skip() const { return frame_skip_; }
  const std::string& source() const { return source_; }
  const std::vector<std::vector<DemoStep>>& episodes() const { return episodes_; }
  int64_t transitions() const;

  static constexpr int kVersion = 1;
  static constexpr const char* kMagic = "hlt-demonstrations";

 private:
  std::string env_;
  int n_, m_, frame_skip_;
  std::string source_;
  std::vector<std::vector<DemoStep>> episodes_;
};

}  // namespace hlt
