// hlt::StochasticHybrid: the paper's Alg. 2 (Theorem 2). A warm-started action plan a_0..a_{H-1} is improved
// each step by K rollouts of the learned dynamics and reward models (or another RolloutModel) with actions
// drawn from an ActionSampler, weighted per time step by exp(J_t / lambda) p(v_t) (J_t the predicted
// reward-to-go), then a_0 is applied. With a PolicySampler this is hybrid learning; with a
// FilteredNoiseSampler it is the NN-MPPI baseline. All K samples move through each step as one batch of
// tensor operations.
#pragma once

#include <functional>
#include <limits>
#include <memory>
#include <vector>

#include "hlt/control/action_sampler.h"
#include "hlt/control/controller.h"
#include "hlt/control/rollout_model.h"
#include "hlt/nn/batched_forward.h"
#include "hlt/nn/dynamics_model.h"
#include "hlt/nn/reward_model.h"

namespace hlt {

struct StochasticHybridOptions {
  int64_t horizon = 5;
  int64_t samples = 20;
  double lambda = 0.1;
  // Include log p(v) in the weights (the paper's Theorem 2). Without it the weights are exp(J / lambda)
  // alone.
  bool density_in_weights = true;
  // Added to every normalised-by-max weight before normalising (the authors' 1e-5): keeps weights positive.
  double weight_floor = 1e-5;
  // If > 0, a time step whose weights would have an effective sample size (1 / sum w^2) below this has
  // its returns' term tempered, J / lambda -> beta J / lambda with the largest beta in [0, 1] that reaches
  // it. 0 (the default) is the paper's rule. Why: where the learned models cannot yet rank the samples,
  // the paper's weights still fall on the one sample the models overrate most, and the planner acts with
  // a single draw of the policy (measured on the Ant imitation task: docs/RESULTS.md).
  double min_ess = 0;
  // Keep every predicted state inside the dynamics model's domain (the per-dimension range of the states
  // it was trained on; DynamicsModelImpl::domain_low/high), clamping after each model step. Why: beyond
  // its data a smooth model extrapolates, and the weights then favour samples for the model's errors there
  // (on the cart-pole, a cart that the model lets run through the end of its rail). No effect until the
  // model has a domain.
  bool clamp_to_domain = false;
  // If > 0, every sample's return also counts this weight times a value estimate of its last predicted
  // state s_H (the controller's TerminalValue), J_t^k = sum_{tau >= t} r_tau^k + weight V(s_H^k). 0 (the
  // default) is the paper's rule, which values nothing beyond the horizon. Why: a few agent steps of
  // lookahead do not see the consequences that decide a task later (on the cart-pole, a cart driven to
  // the end of its rail while the pole falls towards it); SAC's critic, trained on the same data, does.
  double terminal_value_weight = 0;
  // Average the samples where the policy's Gaussian lives, before its tanh: a_t = tanh(sum_k w_t^k
  // atanh(v_t^k)) (v clipped to +-(1 - 1e-6)) instead of the paper's a_t = sum_k w_t^k v_t^k. Why: the
  // average of squashed draws of a broad policy is pulled towards 0 and jitters (E tanh(u) is smaller than
  // tanh(E u)), so where the models cannot yet tell the samples apart the planner acts more timidly than the
  // policy's own action tanh(mu); averaged before the squash, uniform weights give about tanh(mu). Meant for
  // policy samples (a clipped NN-MPPI sample at +-1 counts as atanh(1 - 1e-6) = 7.25).
  bool average_before_squash = false;
};

// A value estimate of states [K, n]: returns [K] (or [K, 1]). Called in inference mode.
using TerminalValue = std::function<at::Tensor(const at::Tensor& states)>;

// The planner's weights [H, K] from scaled returns J / lambda [H, K] and, if given, the samples'
// log-densities [H, K]: per row w ~ exp(beta J / lambda + log p) + floor (after subtracting the row's max),
// normalised, with beta = 1 unless min_ess asks for less (found by bisection, 40 halvings). Returns the
// weights; `betas` (if given) receives each row's beta.
// A sample (column) with a non-finite return or density anywhere, a rollout whose predicted states left
// what the models can represent, gets weight 0 in every row, and the others share the weight as if it had
// not been drawn; with no finite sample the weights are NaN (the controller then falls back).
template <typename T>
RowMatrix<T> planner_weights(const RowMatrix<T>& scaled_returns, const RowMatrix<T>* log_density,
                             double floor, double min_ess,
                             Eigen::Matrix<T, Eigen::Dynamic, 1>* betas = nullptr) {
  const Eigen::Index H = scaled_returns.rows();
  if (betas) betas->setOnes(H);
  if (!scaled_returns.allFinite() || (log_density && !log_density->allFinite())) {
    std::vector<Eigen::Index> valid;
    for (Eigen::Index k = 0; k < scaled_returns.cols(); ++k)
      if (scaled_returns.col(k).allFinite() && (!log_density || log_density->col(k).allFinite()))
        valid.push_back(k);
    if (valid.empty())
      return RowMatrix<T>::Constant(H, scaled_returns.cols(), std::numeric_limits<T>::quiet_NaN());
    RowMatrix<T> j(H, static_cast<Eigen::Index>(valid.size())), d;
    if (log_density) d.resize(H, j.cols());
    for (size_t i = 0; i < valid.size(); ++i) {
      j.col(static_cast<Eigen::Index>(i)) = scaled_returns.col(valid[i]);
      if (log_density) d.col(static_cast<Eigen::Index>(i)) = log_density->col(valid[i]);
    }
    const RowMatrix<T> wv = planner_weights<T>(j, log_density ? &d : nullptr, floor, min_ess, betas);
    RowMatrix<T> w = RowMatrix<T>::Zero(H, scaled_returns.cols());
    for (size_t i = 0; i < valid.size(); ++i)
      w.col(valid[i]) = wv.col(static_cast<Eigen::Index>(i));
    return w;
  }
  // The paper's weights, all rows at once (this exact expression: the methods' logs are bit-exact).
  RowMatrix<T> log_w = scaled_returns;
  if (log_density) log_w += *log_density;
  RowMatrix<T> w = ((log_w.colwise() - log_w.rowwise().maxCoeff()).array().exp() + T(floor)).matrix();
  w.array().colwise() /= w.rowwise().sum().array();
  if (min_ess <= 0) return w;
  auto row_weights = [&](Eigen::Index t, T beta) {
    Eigen::Matrix<T, 1, Eigen::Dynamic> l = beta * scaled_returns.row(t);
    if (log_density) l += log_density->row(t);
    Eigen::Matrix<T, 1, Eigen::Dynamic> e = ((l.array() - l.maxCoeff()).exp() + T(floor)).matrix();
    e /= e.sum();
    return e;
  };
  auto ess = [](const Eigen::Matrix<T, 1, Eigen::Dynamic>& e) {
    return 1.0 / static_cast<double>(e.squaredNorm());
  };
  for (Eigen::Index t = 0; t < H; ++t) {
    if (ess(w.row(t)) >= min_ess) continue;
    // The effective sample size grows as beta falls; keep the largest beta that still reaches min_ess.
    T lo = 0, hi = 1;
    for (int i = 0; i < 40; ++i) {
      const T mid = (lo + hi) / 2;
      (ess(row_weights(t, mid)) >= min_ess ? lo : hi) = mid;
    }
    w.row(t) = row_weights(t, lo);
    if (betas) (*betas)(t) = lo;
  }
  return w;
}

class StochasticHybrid : public Controller {
 public:
  StochasticHybrid(std::shared_ptr<ActionSampler> sampler, DynamicsModel dynamics, RewardModel reward,
                   const StochasticHybridOptions& options, GaussianPolicy fallback_policy = nullptr,
                   std::string name = "stochastic_hybrid", TerminalValue terminal_value = nullptr);
  // The same planner on another model of the environment (options.clamp_to_domain is then the model's
  // business and ignored here).
  StochasticHybrid(std::shared_ptr<ActionSampler> sampler, std::shared_ptr<RolloutModel> model,
                   const StochasticHybridOptions& options, GaussianPolicy fallback_policy = nullptr,
                   std::string name = "stochastic_hybrid", TerminalValue terminal_value = nullptr);

  std::string name() const override { return name_; }
  void reset() override;
  // The current plan [H, m] (after the last call's update).
  const at::Tensor& plan() const { return plan_; }
  // The last call's weights [H, K], sampled actions [H, K, m] and their log-densities [H, K] (computed
  // only with density_in_weights; undefined otherwise).
  const at::Tensor& weights() const { return weights_; }
  const at::Tensor& samples() const { return samples_; }
  const at::Tensor& log_density() const { return log_density_; }
  // The last call's predicted rewards [H, K] of every sample's steps.
  const at::Tensor& rewards() const { return rewards_; }
  // The last call's terminal values V(s_H) [K] (undefined without terminal_value_weight).
  const at::Tensor& terminal_values() const { return terminal_values_; }

 protected:
  at::Tensor compute_action(const at::Tensor& state) override;

 private:
  std::shared_ptr<ActionSampler> sampler_;
  std::shared_ptr<RolloutModel> model_;
  StochasticHybridOptions options_;
  std::string name_;
  TerminalValue terminal_value_;
  at::Tensor plan_, weights_, samples_, log_density_, rewards_, terminal_values_;
  at::Tensor states_a_, states_b_;  // rollout state buffers [K, n] (sample-major)
  std::vector<at::Tensor> plan_rows_, sample_rows_, reward_rows_;  // per-step views
};

}  // namespace hlt
