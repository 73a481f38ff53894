// hlt::Sac: Soft Actor-Critic (Haarnoja et al. 2018, the version with twin soft-Q critics, Polyak-averaged
// target critics and automatic entropy tuning). It owns the critics (one batched TwinQNetwork and its
// target), the entropy temperature and all three optimizers; the policy is shared with the controllers that
// act with it. The critics' parameters and their target's each live in one flat buffer, so the optimizer
// step and the Polyak average are one pass each.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "agents/learner.h"
#include "hlt/data/replay_buffer.h"
#include "hlt/nn/dense_layers.h"
#include "hlt/nn/flat_adam.h"
#include "hlt/nn/gaussian_policy.h"
#include "hlt/nn/twin_q_network.h"

namespace hlt {

struct SacOptions {
  double gamma = 0.99;
  double tau = 0.005;
  double q_lr = 3e-4;
  double policy_lr = 3e-4;
  double alpha_lr = 3e-4;
  std::vector<int64_t> q_hidden = {256, 256};
  double initial_alpha = 1.0;
  // Weight of a behaviour-cloning term on the stored actions in the actor's loss, bc_weight E[-log pi(a|s)]
  // over the batch's (s, a) (0: SAC as published). Why: with a hybrid controller the stored actions are
  // the planner's choices, not the policy's draws; SAC's actor only follows its critic towards them, and
  // where the planner is better than the policy the policy falls behind the actions it is trained on
  // (measured on the cart-pole: docs/RESULTS.md). The term distils the executed actions into the policy,
  // as planners with a learned proposal distribution do. Targets are clipped to +-kBcActionClip. Measured
  // on the cart-pole's stochastic hybrid with weight 1: the policy alone improves, the hybrid does not.
  double bc_weight = 0.0;
  // Entropy target; NaN means -action_dim (the usual heuristic).
  double target_entropy = std::numeric_limits<double>::quiet_NaN();
  // Seed of SAC's own generator (the policy samples of its updates), so that its updates draw the same
  // numbers whatever else runs in the process, concurrently or not.
  uint64_t seed = 0;
};

struct SacLosses {
  double critic = 0;   // mean of the two critics' squared TD errors (each is a mean over the batch)
  double actor = 0;    // E[alpha log pi - min Q]
  double alpha = 0;    // temperature after the update
  double entropy = 0;  // -E[log pi] of the batch's fresh actions
  double bc = 0;       // -E[log pi(a|s)] of the batch's stored actions (computed only with bc_weight > 0)
};

// The behaviour-cloning term's targets: stored actions clipped to this, so that a planner's action at the
// bound asks for tanh(u) = 0.999 (u = 3.8) rather than u = atanh(1 - 1e-6) = 7.25.
inline constexpr double kBcActionClip = 0.999;

class Sac : public Learner {
 public:
  Sac(GaussianPolicy policy, int64_t state_dim, int64_t action_dim, const SacOptions& options);

  // One gradient step of the critics, the policy and the temperature on `batch`. The gradients are
  // written by hand-written backward passes (tested against autograd's in tests/agents/sac_test.cpp).
  SacLosses update(const Batch& batch);
  // The Learner view of update: its losses as loss/critic, loss/actor, sac/alpha, sac/entropy.
  const char* learner_name() const override { return "SAC"; }
  NamedLosses train(const Batch& batch) override;

  GaussianPolicy& policy() { return policy_; }
  // The critics (their .grad()s hold the last update's critic gradient): for tests and analysis.
  TwinQNetwork& critics() { return critics_; }
  double alpha() const;
  double bc_weight() const { return options_.bc_weight; }

  // Everything: policy, critics, targets, temperature, optimizers.
  void save(CheckpointWriter& writer) const;
  void load(CheckpointReader& reader);
  // The same without the policy (which the caller checkpoints with the other shared networks).
  void save_training_state(CheckpointWriter& writer) const override;
  void load_training_state(CheckpointReader& reader) override;

 private:
  SacOptions options_;
  double target_entropy_;
  GaussianPolicy policy_;
  TwinQNetwork critics_{nullptr}, critics_target_{nullptr};
  torch::Tensor log_alpha_;
  std::unique_ptr<FlatAdam> q_opt_, policy_opt_, alpha_opt_;
  torch::Tensor target_flat_;  // the target critics' parameters, in the critics' flat order
  at::Generator generator_;
  DenseStack mean_pass_, log_std_pass_;  // the policy's two heads, for the hand-written actor gradient
};

}  // namespace hlt
