// Fixed policies named by a string, as the tools and the imitation loop's demonstrator take them: the
// ones of envs/rollout.h ("zero", "random", "constant:V[,...]", "scripted:NAME" for an environment's scripted
// expert), "expert:PATH" (ExpertPolicy) and "oracle:H,K[,LAMBDA[,NOISE]]" (OraclePolicy: MPPI on a copy of
// the environment, which must then outlive the policy).
// Trained policies ("checkpoint:PATH") are loaded by agents/saved_policy.h, which also needs to know the
// frame skip before the environment is built.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <random>
#include <string>

#include "envs/env.h"
#include "envs/rollout.h"

namespace hlt {

// Throws hlt::Error for an unknown spec, an unreadable expert, or an expert whose sizes are not `env`'s;
// `what` names the setting in the message (e.g. "--policy"). `seed` seeds the random policy.
std::unique_ptr<PolicySource> make_fixed_policy(const std::string& spec, const Env& env, uint64_t seed,
                                                const std::string& what);

// `inner` with Gaussian noise of standard deviation `sigma` added to every action component, the sum clipped
// to [-1, 1]. Its intended action is the noiseless one (inner's own intended action where it has one), so a
// demonstrator so wrapped runs off its nominal path while imitation can learn its clean labels (DART, Laskey
// et al. 2017), and the learned models see how other actions than the expert's move the system.
class NoisyPolicy : public PolicySource {
 public:
  // Precondition: sigma >= 0 (checked). `seed` seeds the noise.
  NoisyPolicy(std::unique_ptr<PolicySource> inner, double sigma, uint64_t seed);
  std::string describe() const override;
  Eigen::VectorXd act(const Eigen::VectorXd& observation) override;
  std::optional<Eigen::VectorXd> intended_action() const override { return intended_; }

 private:
  std::unique_ptr<PolicySource> inner_;
  double sigma_;
  std::mt19937_64 rng_;
  std::optional<Eigen::VectorXd> intended_;
};

}  // namespace hlt
