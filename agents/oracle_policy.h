// hlt::OraclePolicy ("oracle:H,K[,LAMBDA[,NOISE]]"): MPPI that plans on a copy of the environment itself.
// Before every action it restores the copy to the real environment's snapshot, rolls out K Gaussian
// perturbations (standard deviation NOISE, clipped to [-1, 1]) of its warm-started H-step plan, and acts with
// their exp(J / LAMBDA)-weighted average (J the sampled return). It answers what a planner with these
// settings can do with a perfect model: the bound for the learned models of the hybrid methods and NN-MPPI,
// which plan with the same H, K and lambda (e.g. docs/RESULTS.md's block pushing). It reads the real
// environment's state, which no learner sees, so it is a measuring instrument, not a method.
#pragma once

#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "envs/env.h"
#include "envs/rollout.h"

namespace hlt {

struct OracleOptions {
  int horizon = 10;
  int samples = 10;
  double lambda = 0.01;
  double noise = 0.5;
};

class OraclePolicy : public PolicySource {
 public:
  static constexpr const char* kPrefix = "oracle:";
  // Parses "H,K[,LAMBDA[,NOISE]]" (the part after kPrefix); throws hlt::Error naming the form.
  static OracleOptions parse(const std::string& spec);

  // `env` (a registered environment, possibly frame-skipped) must outlive this; the policy acts in it, and
  // plans on its own copy, built by name. The generator for the perturbations is seeded with `seed`.
  OraclePolicy(const Env& env, const OracleOptions& options, uint64_t seed);
  std::string describe() const override;
  // Plans from the real environment's current state (`observation` is only checked for size). A new
  // episode (the environment at step 0) starts from an empty plan.
  Eigen::VectorXd act(const Eigen::VectorXd& observation) override;

 private:
  const Env& env_;
  std::unique_ptr<Env> sim_;
  OracleOptions options_;
  std::mt19937_64 rng_;
  Eigen::MatrixXd plan_;  // [H, m]
};

}  // namespace hlt
