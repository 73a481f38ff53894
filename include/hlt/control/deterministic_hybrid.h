// hlt::DeterministicHybrid: the paper's Alg. 1 (Lemma 1, Theorem 1, Corollary 1) in discrete time.
//
// From the observed s0 it rolls the learned dynamics forward under the policy mean, gets every Jacobian it
// needs by autograd (all H steps in one batched backward pass), sweeps the adjoint backwards,
// rho_t = g_t + A_t^T rho_{t+1} with rho_H = 0, A_t = df/ds + df/da dmu/ds, g_t = dr/ds + dr/da dmu/ds, and
// applies a* = mu(s0) + Sigma(s0) (dr/da|_0 + B_0^T rho_1) + eps, clipped to [-1, 1] (the exact rule; see
// DeterministicActionRule for the bounded rule the training config uses by default), where
// eps ~ N(0, decay^t) over all environment interactions t (agent steps), or the policy's own noise
// (DeterministicExploration). It reports the mode insertion gradient (r(s0, a*) - r(s0, mu(s0))) +
// rho_1^T (f(s0, a*) - f(s0, mu(s0))). Without a policy (mu = 0, Sigma = I) it is the model-based
// deterministic baseline.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "hlt/control/controller.h"
#include "hlt/nn/batched_forward.h"
#include "hlt/nn/dynamics_model.h"
#include "hlt/nn/reward_model.h"

namespace hlt {

// How much of the exact adjoint reaches the action.
enum class DeterministicActionRule {
  // The paper's Theorem 1 in discrete time: a* = mu(s0) + Sigma(s0) (dr/da|_0 + B_0^T rho_1), mu =
  // tanh(mu_raw),
  // rho clamped only if clamp_adjoint. The correction is the exact derivative of the predicted return scaled
  // by the variance; early in training it is tens of units wide and saturates a*.
  kExact,
  // The authors' rule (their deter_wrapper_v1.py), a bounded reading of Theorem 1's local validity:
  // a* = mu_raw + Sigma (1 - tanh^2(mu_raw)) B_0^T clamp(rho_0, -1, 1), then clipped to [-1, 1]. It differs
  // from a* = Sigma h^T rho + mu in three ways: rho is clamped to [-1, 1] elementwise (always, whatever
  // clamp_adjoint says); the derivative is taken w.r.t. the pre-tanh mean u (the Gaussian the variance
  // Sigma belongs to), hence the factor 1 - tanh^2(mu_raw), and added to mu_raw, not to tanh(mu_raw); and h^T
  // rho
  // is evaluated with the adjoint at the switch time, rho_0 (the continuous-time Theorem 1's rho(tau)),
  // without the separate dr/da|_0 term of the exact discrete derivative. The exact rho is still computed
  // (trace().rho, dreturn_da0) and the mode insertion gradient still uses it.
  kBounded,
  // The bounded correction, squashed: a* = tanh(mu_raw + Sigma (1 - tanh^2(mu_raw)) B_0^T clamp(rho_0, -1,
  // 1)). The step is the bounded rule's, taken in the Gaussian's pre-tanh space and mapped to an action the
  // way the policy maps its own samples, so that zero correction is the policy's action exactly, as in the
  // paper's a* = mu + Sigma h^T rho (under kBounded a vanishing correction executes clip(mu_raw), up to
  // 0.24 away from tanh(mu_raw) at |mu_raw| = 1). Measured on the cart-pole, seeds 0-9, it learns as
  // kBounded does (docs/RESULTS.md, issue 11), so it is an option, not the default.
  kBoundedSquashed,
};

// Where the exploration noise of a training action comes from.
enum class DeterministicExploration {
  // eps ~ N(0, decay^t) added to the clipped a* (the authors' schedule): gone after a few thousand agent
  // steps, after which every stored action is the planner's deterministic one.
  kDecay,
  // The policy's own Gaussian: the noise Sigma^(1/2) eps is added to the pre-tanh mean before the rule
  // squashes or clips it, so that with zero correction the executed action is a draw of the policy, as SAC's
  // own behaviour is, and the exploration left is whatever entropy SAC's temperature keeps. Without a policy
  // (the model-based baseline) it falls back to kDecay.
  kPolicy,
};

struct DeterministicHybridOptions {
  int64_t horizon = 5;
  // The authors clamp rho to [-1, 1] before use; off by default (the unclamped rho is the exact gradient).
  bool clamp_adjoint = false;
  // Exploration noise std = exploration_decay^t (t counts environment interactions, i.e. agent steps;
  // 0.999 in the paper).
  double exploration_decay = 0.999;
  bool explore = true;
  DeterministicExploration exploration = DeterministicExploration::kDecay;
  DeterministicActionRule rule = DeterministicActionRule::kExact;
};

// Everything the adjoint sweep computed for the last state, for tests and diagnostics. Row-major Eigen
// matrices in double precision.
struct AdjointTrace {
  Eigen::MatrixXd states;       // [H + 1, n] closed-loop trajectory s_0..s_H
  Eigen::MatrixXd actions;      // [H, m] mu(s_t)
  Eigen::MatrixXd rho;          // [H + 1, n] rho_0..rho_H (rho_H = 0)
  Eigen::VectorXd dreturn_da0;  // [m] dr/da|_0 + B_0^T rho_1: derivative of the predicted return w.r.t. a_0
  Eigen::VectorXd sigma;        // [m] the policy variance at s0 (ones without a policy)
  Eigen::VectorXd mean_action;  // [m] mu(s0) = tanh(mu_raw(s0)) (zero without a policy)
  Eigen::VectorXd mean_raw;     // [m] mu_raw(s0), the policy's pre-tanh mean (zero without a policy)
  Eigen::VectorXd action;       // [m] a* before exploration noise and clipping
  Eigen::VectorXd correction;   // [m] what the rule adds to the policy: to mu (exact) or to mu_raw (bounded)
};

// Jacobians of the models along a trajectory, by autograd, all steps in one backward pass. Row blocks per
// step: fs rows [t n, t n + n) hold d f / d s at step t (n x n), fa the n x m d f / d a, mus the m x n
// d mu / d s (zero without a policy); rs and ra hold d r / d s and d r / d a as rows.
struct ModelJacobians {
  Eigen::MatrixXd fs, fa, mus, rs, ra;
};
// `states` [H, n] and `actions` [H, m] in the models' dtype; `policy` may be nullptr.
ModelJacobians model_jacobians(DynamicsModel& dynamics, RewardModel& reward, GaussianPolicy& policy,
                               const at::Tensor& states, const at::Tensor& actions);

class DeterministicHybrid : public Controller {
 public:
  // `policy` may be nullptr: the model-based baseline.
  DeterministicHybrid(GaussianPolicy policy, DynamicsModel dynamics, RewardModel reward,
                      const DeterministicHybridOptions& options, std::string name = "deterministic_hybrid");

  std::string name() const override { return name_; }
  // Number of environment interactions (agent steps) so far, which drives the exploration decay; the
  // training loop sets it.
  void set_interactions(int64_t t) override { interactions_ = t; }
  void set_explore(bool explore) { options_.explore = explore; }
  const AdjointTrace& trace() const { return trace_; }
  // Runs the forward rollout, Jacobians and adjoint sweep for `state` without acting.
  const AdjointTrace& analyse(const at::Tensor& state);

 protected:
  at::Tensor compute_action(const at::Tensor& state) override;

 private:
  // rho_t as the action and the mode insertion gradient use it (clamped if configured).
  Eigen::VectorXd adjoint_used(int64_t t) const;

  GaussianPolicy policy_;
  DynamicsModel dynamics_;
  RewardModel reward_;
  ModelForward models_;  // batches of one: the rollout and the mode insertion gradient
  std::optional<PolicyForward> policy_forward_;
  DeterministicHybridOptions options_;
  std::string name_;
  int64_t interactions_ = 0;
  AdjointTrace trace_;
  at::Tensor X_, A_, reward0_;  // the rollout: states [H + 1, n], actions [H, m], r(s0, mu(s0)) [1]
  std::vector<at::Tensor> x_rows_, a_rows_;        // their rows as [1, n] / [1, m] batches of one
  at::Tensor mig_action_, mig_next_, mig_reward_;  // a* [1, m], f(s0, a*) [1, n], r(s0, a*) [1]
};

}  // namespace hlt
