#include "hlt/control/deterministic_hybrid.h"

#include <cmath>

#include <torch/torch.h>

#include "hlt/util/error.h"

namespace hlt {
namespace {

// A contiguous double copy of `t` viewed as a row-major Eigen matrix of `rows` x `cols`.
Eigen::MatrixXd to_eigen(const at::Tensor& t, int64_t rows, int64_t cols) {
  const at::Tensor d = t.detach().to(torch::kFloat64).contiguous();
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  return Eigen::Map<const RowMajor>(d.data_ptr<double>(), rows, cols);
}

}  // namespace

ModelJacobians model_jacobians(DynamicsModel& dynamics, RewardModel& reward, GaussianPolicy& policy,
                               const at::Tensor& states, const at::Tensor& actions) {
  const int64_t H = states.size(0), n = states.size(1), m = actions.size(1);
  const auto opts = states.options().requires_grad(false);
  // Each output row gets its own copy of the input (n copies for f, m for mu) and an identity seed picks
  // that row's gradient, so one backward pass yields every row of every Jacobian at every step.
  at::Tensor Sf = states.repeat_interleave(n, 0).requires_grad_(true);   // [H n, n]
  at::Tensor Af = actions.repeat_interleave(n, 0).requires_grad_(true);  // [H n, m]
  at::Tensor Sr = states.clone().requires_grad_(true);                   // [H, n]
  at::Tensor Ar = actions.clone().requires_grad_(true);                  // [H, m]
  at::Tensor total =
      (dynamics->forward(Sf, Af) * torch::eye(n, opts).repeat({H, 1})).sum() + reward->forward(Sr, Ar).sum();
  std::vector<at::Tensor> inputs{Sf, Af, Sr, Ar};
  const bool has_policy = !policy.is_empty();
  if (has_policy) {
    at::Tensor Smu = states.repeat_interleave(m, 0).requires_grad_(true);  // [H m, n]
    total = total + (policy->mean_action(Smu) * torch::eye(m, opts).repeat({H, 1})).sum();
    inputs.push_back(Smu);
  }
  const auto grads = torch::autograd::grad({total}, inputs);
  ModelJacobians J;
  J.fs = to_eigen(grads[0], H * n, n);
  J.fa = to_eigen(grads[1], H * n, m);
  J.rs = to_eigen(grads[2], H, n);
  J.ra = to_eigen(grads[3], H, m);
  J.mus = has_policy ? to_eigen(grads[4], H * m, n) : Eigen::MatrixXd::Zero(H * m, n);
  return J;
}

DeterministicHybrid::DeterministicHybrid(GaussianPolicy policy, DynamicsModel dynamics, RewardModel reward,
                                         const DeterministicHybridOptions& options, std::string name)
    : Controller(policy),
      policy_(std::move(policy)),
      dynamics_(std::move(dynamics)),
      reward_(std::move(reward)),
      options_(options),
      name_(std::move(name)) {
  check(options.horizon >= 1, "{}: horizon must be >= 1", name_);
}

const AdjointTrace& DeterministicHybrid::analyse(const at::Tensor& state) {
  const int64_t H = options_.horizon;
  const int64_t n = dynamics_->options().state_dim, m = dynamics_->options().action_dim;
  const bool has_policy = !policy_.is_empty();
  const auto opts = dynamics_->fc1->weight.options().requires_grad(false);
  check(state.numel() == n, "{}: state has {} values, the model expects {}", name_, state.numel(), n);

  // 1. Forward rollout under the policy mean (zero action without a policy).
  at::Tensor X = torch::empty({H + 1, n}, opts), A = torch::zeros({H, m}, opts);
  at::Tensor log_std0;
  {
    torch::NoGradGuard no_grad;
    X[0] = state.to(opts.dtype());
    at::Tensor s = X.narrow(0, 0, 1);
    for (int64_t t = 0; t < H; ++t) {
      if (has_policy) {
        auto [mean, log_std] = policy_->forward(s);
        if (t == 0) log_std0 = log_std;
        A[t] = mean.tanh().squeeze(0);
      }
      s = dynamics_->forward(s, A.narrow(0, t, 1));
      X[t + 1] = s.squeeze(0);
    }
  }

  // 2. Jacobians of f, r and mu at all H steps, batched.
  const ModelJacobians J = model_jacobians(dynamics_, reward_, policy_, X.narrow(0, 0, H), A);
  const Eigen::MatrixXd &fs = J.fs, &fa = J.fa, &rs = J.rs, &ra = J.ra, &mus = J.mus;

  // 3. Adjoint sweep: rho_t = g_t + A_t^T rho_{t+1}, the gradient of the predicted reward-to-go w.r.t. s_t.
  AdjointTrace& tr = trace_;
  tr.states = to_eigen(X, H + 1, n);
  tr.actions = to_eigen(A, H, m);
  tr.rho = Eigen::MatrixXd::Zero(H + 1, n);
  for (int64_t t = H - 1; t >= 0; --t) {
    const auto Fs = fs.middleRows(t * n, n), Fa = fa.middleRows(t * n, n), Mu = mus.middleRows(t * m, m);
    const Eigen::MatrixXd At = Fs + Fa * Mu;
    const Eigen::VectorXd gt = rs.row(t).transpose() + Mu.transpose() * ra.row(t).transpose();
    tr.rho.row(t) = (gt + At.transpose() * tr.rho.row(t + 1).transpose()).transpose();
  }

  // 4. The best action (Theorem 1, discrete): mu(s0) + Sigma(s0) (dr/da|_0 + B_0^T rho_1).
  Eigen::VectorXd rho1 = tr.rho.row(1).transpose();
  if (options_.clamp_adjoint) rho1 = rho1.cwiseMax(-1.0).cwiseMin(1.0);
  tr.dreturn_da0 = ra.row(0).transpose() + fa.middleRows(0, n).transpose() * rho1;
  tr.mean_action = tr.actions.row(0).transpose();
  tr.sigma =
      has_policy ? Eigen::VectorXd(to_eigen((2.0 * log_std0).exp(), m, 1).col(0)) : Eigen::VectorXd::Ones(m);
  tr.action = tr.mean_action + tr.sigma.cwiseProduct(tr.dreturn_da0);
  return tr;
}

at::Tensor DeterministicHybrid::compute_action(const at::Tensor& state) {
  const AdjointTrace& tr = analyse(state);
  const int64_t n = tr.states.cols(), m = tr.action.size();
  const auto opts = dynamics_->fc1->weight.options().requires_grad(false);
  const Eigen::VectorXd a_star = tr.action.cwiseMax(-1.0).cwiseMin(1.0);

  // 5. Mode insertion gradient (eq. 5, discrete): the predicted gain of switching from mu(s0) to a*.
  {
    torch::InferenceMode guard;
    Eigen::VectorXd s0v = tr.states.row(0).transpose();
    const at::Tensor s0 =
        torch::from_blob(s0v.data(), {1, n}, torch::kFloat64).to(opts.dtype()).expand({2, n});
    Eigen::MatrixXd acts(2, m);
    acts.row(0) = a_star.transpose();
    acts.row(1) = tr.mean_action.transpose();
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> acts_rm = acts;
    at::Tensor a2 = torch::from_blob(acts_rm.data(), {2, m}, torch::kFloat64).to(opts.dtype());
    const Eigen::MatrixXd f = to_eigen(dynamics_->forward(s0, a2), 2, n);
    const Eigen::MatrixXd r = to_eigen(reward_->forward(s0, a2), 2, 1);
    Eigen::VectorXd rho1 = tr.rho.row(1).transpose();
    if (options_.clamp_adjoint) rho1 = rho1.cwiseMax(-1.0).cwiseMin(1.0);
    diagnostics_.mode_insertion_gradient = (r(0, 0) - r(1, 0)) + rho1.dot((f.row(0) - f.row(1)).transpose());
  }

  Eigen::VectorXd action = a_star;
  if (options_.explore) {
    const double std = std::pow(options_.exploration_decay, static_cast<double>(interactions_));
    action += std * to_eigen(torch::randn({m}, torch::kFloat64), m, 1).col(0);
  }
  return torch::from_blob(action.data(), {m}, torch::kFloat64).to(opts.dtype()).clone();
}

}  // namespace hlt
