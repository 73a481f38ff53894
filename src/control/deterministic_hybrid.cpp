#include "hlt/control/deterministic_hybrid.h"

#include <cmath>

#include <torch/torch.h>

#include "hlt/util/error.h"

namespace hlt {
namespace {

// A double copy of the 2-D tensor `t` (rows contiguous), as an Eigen matrix; no dispatched ops.
Eigen::MatrixXd to_eigen(const at::Tensor& t) {
  Eigen::MatrixXd out;
  dispatch_floating(t, [&](auto tag) {
    using T = decltype(tag);
    out = row_map<T>(t).template cast<double>();
  });
  return out;
}

// `rows` [H, w] with each row repeated `copies` times in a row, [H copies, w] (repeat_interleave without its
// index tensor and dispatched ops).
at::Tensor repeated_rows(const at::Tensor& rows, int64_t copies) {
  at::Tensor out = at::empty({rows.size(0) * copies, rows.size(1)}, rows.options().requires_grad(false));
  dispatch_floating(rows, [&](auto tag) {
    using T = decltype(tag);
    const auto src = row_map<T>(rows);
    auto dst = row_map<T>(out);
    for (Eigen::Index i = 0; i < src.rows(); ++i)
      dst.middleRows(i * copies, copies).rowwise() = src.row(i);
  });
  return out;
}

// [size x size] identity blocks stacked `blocks` times: the seed that selects one output row per input copy.
at::Tensor stacked_identity(int64_t blocks, int64_t size, const at::TensorOptions& opts) {
  at::Tensor out = at::zeros({blocks * size, size}, opts);
  dispatch_floating(out, [&](auto tag) {
    using T = decltype(tag);
    auto dst = row_map<T>(out);
    for (int64_t b = 0; b < blocks; ++b)
      dst.middleRows(b * size, size).diagonal().setOnes();
  });
  return out;
}

}  // namespace

ModelJacobians model_jacobians(DynamicsModel& dynamics, RewardModel& reward, GaussianPolicy& policy,
                               const at::Tensor& states, const at::Tensor& actions) {
  const int64_t H = states.size(0), n = states.size(1), m = actions.size(1);
  const auto opts = states.options().requires_grad(false);
  // Each output row gets its own copy of the input (n copies for f, m for mu) and an identity seed picks
  // that row's gradient, so one backward pass yields every row of every Jacobian at every step. Each network
  // is a single autograd node (dense_chain): the engine's per-node cost, not the products, dominated this
  // pass through the modules' forward (docs/BENCHMARKS.md).
  at::Tensor Sf = repeated_rows(states, n).requires_grad_(true);   // [H n, n]
  at::Tensor Af = repeated_rows(actions, n).requires_grad_(true);  // [H n, m]
  at::Tensor Sr = states.detach().requires_grad_(true);            // [H, n]
  at::Tensor Ar = actions.detach().requires_grad_(true);           // [H, m]
  std::vector<at::Tensor> outputs{dense_chain(dynamics->chain(), {Sf, Af}),
                                  dense_chain(reward->chain(), {Sr, Ar})};
  std::vector<at::Tensor> seeds{stacked_identity(H, n, opts), at::ones({H, 1}, opts)};
  std::vector<at::Tensor> inputs{Sf, Af, Sr, Ar};
  const bool has_policy = !policy.is_empty();
  if (has_policy) {
    at::Tensor Smu = repeated_rows(states, m).requires_grad_(true);  // [H m, n]
    outputs.push_back(dense_chain(policy->mean_chain(), {Smu}));
    seeds.push_back(stacked_identity(H, m, opts));
    inputs.push_back(Smu);
  }
  const auto grads = torch::autograd::grad(outputs, inputs, seeds);
  ModelJacobians J;
  J.fs = to_eigen(grads[0]);
  J.fa = to_eigen(grads[1]);
  J.rs = to_eigen(grads[2]);
  J.ra = to_eigen(grads[3]);
  J.mus = has_policy ? to_eigen(grads[4]) : Eigen::MatrixXd::Zero(H * m, n);
  return J;
}

DeterministicHybrid::DeterministicHybrid(GaussianPolicy policy, DynamicsModel dynamics, RewardModel reward,
                                         const DeterministicHybridOptions& options, std::string name)
    : Controller(policy),
      policy_(std::move(policy)),
      dynamics_(dynamics),
      reward_(reward),
      models_(dynamics, reward),
      options_(options),
      name_(std::move(name)) {
  check(options.horizon >= 1, "{}: horizon must be >= 1", name_);
  // The adjoint sweep differentiates r(s_t, a_t); a reward of the reached state would need f's Jacobian
  // inside each step's reward term.
  check(!reward_->options().reads_next_state,
        "{}: the reward model reads the next state (model.reward_input next_state); the adjoint sweep needs "
        "r(s, a) (model.reward_input state)",
        name_);
  if (!policy_.is_empty()) policy_forward_.emplace(policy_);
}

const AdjointTrace& DeterministicHybrid::analyse(const at::Tensor& state) {
  const int64_t H = options_.horizon;
  const int64_t n = dynamics_->options().state_dim, m = dynamics_->options().action_dim;
  const bool has_policy = policy_forward_.has_value();
  check(state.numel() == n, "{}: state has {} values, the model expects {}", name_, state.numel(), n);
  const auto opts = dynamics_->fc1->weight.options().requires_grad(false);
  if (!X_.defined() || X_.scalar_type() != opts.dtype()) {
    X_ = torch::empty({H + 1, n}, opts);
    A_ = torch::empty({H, m}, opts);
    reward0_ = torch::empty({1}, opts);
    // A batch of one is a row [1, n] of X (and [1, m] of A).
    x_rows_.clear();
    a_rows_.clear();
    for (int64_t t = 0; t <= H; ++t)
      x_rows_.push_back(X_[t].view({1, n}));
    for (int64_t t = 0; t < H; ++t)
      a_rows_.push_back(A_[t].view({1, m}));
  }
  AdjointTrace& tr = trace_;

  // 1. Forward rollout under the policy mean (zero action without a policy), batch of one. InferenceMode,
  // not only no gradients: its ~40 dispatched ops then skip autograd's bookkeeping too. The buffers the
  // batched passes create here are used in inference mode only (the mode insertion gradient's step is too).
  {
    torch::InferenceMode guard;
    X_[0].copy_(state);
    models_.prepare(1);
    if (has_policy) policy_forward_->prepare(1);
    Eigen::VectorXd log_std0 = Eigen::VectorXd::Zero(m);
    tr.mean_raw = Eigen::VectorXd::Zero(m);
    dispatch_floating(X_, [&](auto tag) {
      using T = decltype(tag);
      row_map<T>(A_).setZero();
      for (int64_t t = 0; t < H; ++t) {
        if (has_policy) {
          policy_forward_->forward(x_rows_[t]);
          row_map<T>(a_rows_[t]) = row_map<T>(policy_forward_->mean()).array().tanh().matrix();
          if (t == 0) {
            log_std0 = row_map<T>(policy_forward_->log_std()).row(0).transpose().template cast<double>();
            tr.mean_raw = row_map<T>(policy_forward_->mean()).row(0).transpose().template cast<double>();
          }
        }
        // r(s0, mu(s0)) is kept for the mode insertion gradient.
        models_.step(x_rows_[t], a_rows_[t], x_rows_[t + 1], t == 0 ? &reward0_ : nullptr);
      }
    });
    tr.sigma = has_policy ? Eigen::VectorXd((2.0 * log_std0).array().exp()) : Eigen::VectorXd::Ones(m);
  }

  // 2. Jacobians of f, r and mu at all H steps, batched.
  const ModelJacobians J = model_jacobians(dynamics_, reward_, policy_, X_.narrow(0, 0, H), A_);

  // 3. Adjoint sweep: rho_t = g_t + A_t^T rho_{t+1}, the gradient of the predicted reward-to-go w.r.t. s_t.
  tr.states = to_eigen(X_);
  tr.actions = to_eigen(A_);
  tr.rho = Eigen::MatrixXd::Zero(H + 1, n);
  for (int64_t t = H - 1; t >= 0; --t) {
    const auto Fs = J.fs.middleRows(t * n, n), Fa = J.fa.middleRows(t * n, n),
               Mu = J.mus.middleRows(t * m, m);
    const Eigen::MatrixXd At = Fs + Fa * Mu;
    const Eigen::VectorXd gt = J.rs.row(t).transpose() + Mu.transpose() * J.ra.row(t).transpose();
    tr.rho.row(t) = (gt + At.transpose() * tr.rho.row(t + 1).transpose()).transpose();
  }

  // 4. The best action (Theorem 1, discrete): mu(s0) + Sigma(s0) (dr/da|_0 + B_0^T rho_1).
  tr.dreturn_da0 = J.ra.row(0).transpose() + J.fa.middleRows(0, n).transpose() * adjoint_used(1);
  tr.mean_action = tr.actions.row(0).transpose();
  if (options_.rule != DeterministicActionRule::kExact) {
    // mu_raw + Sigma (1 - tanh^2(mu_raw)) B_0^T clamp(rho_0, -1, 1), squashed by tanh under kBoundedSquashed.
    const Eigen::VectorXd rho0 = tr.rho.row(0).transpose().cwiseMax(-1.0).cwiseMin(1.0);
    const Eigen::VectorXd dtanh = (1.0 - tr.mean_raw.array().tanh().square()).matrix();
    const Eigen::VectorXd correction = dtanh.cwiseProduct(J.fa.middleRows(0, n).transpose() * rho0);
    tr.correction = tr.sigma.cwiseProduct(correction);
    tr.action = tr.mean_raw + tr.correction;
    if (options_.rule == DeterministicActionRule::kBoundedSquashed)
      tr.action = tr.action.array().tanh().matrix();
  } else {
    tr.correction = tr.sigma.cwiseProduct(tr.dreturn_da0);
    tr.action = tr.mean_action + tr.correction;
  }
  return tr;
}

Eigen::VectorXd DeterministicHybrid::adjoint_used(int64_t t) const {
  Eigen::VectorXd rho = trace_.rho.row(t).transpose();
  if (options_.clamp_adjoint) rho = rho.cwiseMax(-1.0).cwiseMin(1.0);
  return rho;
}

at::Tensor DeterministicHybrid::compute_action(const at::Tensor& state) {
  const AdjointTrace& tr = analyse(state);
  const int64_t n = tr.states.cols(), m = tr.action.size();
  const Eigen::VectorXd a_star = tr.action.cwiseMax(-1.0).cwiseMin(1.0);

  // 5. Mode insertion gradient (eq. 5, discrete): the predicted gain of switching from mu(s0) to a* for one
  // step, (r(s0, a*) - r(s0, mu)) + rho_1^T (f(s0, a*) - f(s0, mu)). f(s0, mu) = s_1 and r(s0, mu) come from
  // the rollout; the models are still prepared for its batch of one.
  {
    torch::InferenceMode guard;
    const auto opts = dynamics_->fc1->weight.options().requires_grad(false);
    if (!mig_action_.defined() || mig_action_.scalar_type() != opts.dtype()) {
      mig_action_ = torch::empty({1, m}, opts);
      mig_next_ = torch::empty({1, n}, opts);
      mig_reward_ = torch::empty({1}, opts);
    }
    dispatch_floating(mig_action_, [&](auto tag) {
      using T = decltype(tag);
      row_map<T>(mig_action_).row(0) = a_star.transpose().template cast<T>();
    });
    models_.step(x_rows_[0], mig_action_, mig_next_, &mig_reward_);
    const Eigen::MatrixXd f = to_eigen(mig_next_);
    const double r_star = to_eigen(mig_reward_.view({1, 1}))(0, 0),
                 r_mu = to_eigen(reward0_.view({1, 1}))(0, 0);
    diagnostics_.mode_insertion_gradient =
        (r_star - r_mu) + adjoint_used(1).dot((f.row(0) - tr.states.row(1)).transpose());
  }

  Eigen::VectorXd action = a_star;
  if (options_.explore && options_.exploration == DeterministicExploration::kPolicy &&
      policy_forward_.has_value()) {
    // A draw u = mu_raw + Sigma^(1/2) eps of the policy's Gaussian takes the place of mu_raw in the rule.
    const Eigen::VectorXd u = tr.mean_raw + tr.sigma.cwiseSqrt().cwiseProduct(
                                                to_eigen(torch::randn({m, 1}, torch::kFloat64)).col(0));
    switch (options_.rule) {
      case DeterministicActionRule::kExact:
        action = u.array().tanh().matrix() + tr.correction;
        break;
      case DeterministicActionRule::kBounded:
        action = u + tr.correction;
        break;
      case DeterministicActionRule::kBoundedSquashed:
        action = (u + tr.correction).array().tanh().matrix();
        break;
    }
    action = action.cwiseMax(-1.0).cwiseMin(1.0);
  } else if (options_.explore) {
    const double std = std::pow(options_.exploration_decay, static_cast<double>(interactions_));
    action += std * to_eigen(torch::randn({m, 1}, torch::kFloat64)).col(0);
  }
  at::Tensor out = torch::empty({m}, dynamics_->fc1->weight.options().requires_grad(false));
  dispatch_floating(out, [&](auto tag) {
    using T = decltype(tag);
    Eigen::Map<Eigen::Matrix<T, Eigen::Dynamic, 1>>(out.data_ptr<T>(), m) = action.template cast<T>();
  });
  return out;
}

}  // namespace hlt
