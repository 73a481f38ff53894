#include "hlt/control/stochastic_hybrid.h"

#include <torch/torch.h>

#include "hlt/util/error.h"

namespace hlt {

StochasticHybrid::StochasticHybrid(std::shared_ptr<ActionSampler> sampler, DynamicsModel dynamics,
                                   RewardModel reward, const StochasticHybridOptions& options,
                                   GaussianPolicy fallback_policy, std::string name,
                                   TerminalValue terminal_value)
    : StochasticHybrid(std::move(sampler),
                       std::make_shared<LearnedRolloutModel>(std::move(dynamics), std::move(reward),
                                                             options.clamp_to_domain),
                       options, std::move(fallback_policy), std::move(name), std::move(terminal_value)) {}

StochasticHybrid::StochasticHybrid(std::shared_ptr<ActionSampler> sampler,
                                   std::shared_ptr<RolloutModel> model,
                                   const StochasticHybridOptions& options, GaussianPolicy fallback_policy,
                                   std::string name, TerminalValue terminal_value)
    : Controller(std::move(fallback_policy)),
      sampler_(std::move(sampler)),
      model_(std::move(model)),
      options_(options),
      name_(std::move(name)),
      terminal_value_(std::move(terminal_value)) {
  check(sampler_ != nullptr, "{}: needs an action sampler", name_);
  check(model_ != nullptr, "{}: needs a model to plan on", name_);
  check(options.horizon >= 1 && options.samples >= 1, "{}: horizon and samples must be >= 1", name_);
  check(options.lambda > 0, "{}: lambda must be > 0, got {}", name_, options.lambda);
  check(options.min_ess >= 0 && options.min_ess <= static_cast<double>(options.samples),
        "{}: min_ess must be in [0, samples = {}], got {}", name_, options.samples, options.min_ess);
  check(options.terminal_value_weight >= 0, "{}: terminal_value_weight must be >= 0, got {}", name_,
        options.terminal_value_weight);
  check(options.terminal_value_weight == 0 || terminal_value_,
        "{}: terminal_value_weight {} needs a value function", name_, options.terminal_value_weight);
  reset();
}

void StochasticHybrid::reset() {
  const auto opts = torch::TensorOptions().dtype(model_->dtype());
  if (plan_.defined() && plan_.scalar_type() == opts.dtype()) {
    plan_.zero_();
    return;
  }
  const int64_t H = options_.horizon, K = options_.samples, m = model_->action_dim();
  const int64_t n = model_->state_dim();
  // Buffers live as long as the controller; the per-step views into them are made once here.
  plan_ = torch::zeros({H, m}, opts);
  states_a_ = torch::empty({K, n}, opts);
  states_b_ = torch::empty({K, n}, opts);
  samples_ = torch::empty({H, K, m}, opts);
  rewards_ = torch::empty({H, K}, opts);
  weights_ = torch::empty({H, K}, opts);
  plan_rows_.clear();
  sample_rows_.clear();
  reward_rows_.clear();
  for (int64_t t = 0; t < H; ++t) {
    plan_rows_.push_back(plan_[t]);
    sample_rows_.push_back(samples_[t]);
    reward_rows_.push_back(rewards_[t]);
  }
}

at::Tensor StochasticHybrid::compute_action(const at::Tensor& state) {
  torch::InferenceMode guard;
  const int64_t H = options_.horizon, K = options_.samples, m = plan_.size(1);
  const int64_t n = model_->state_dim();
  check(state.numel() == n, "{}: state has {} values, the model expects {}", name_, state.numel(), n);
  const at::Tensor s0 =
      state.scalar_type() == plan_.scalar_type() ? state.contiguous() : state.to(plan_.scalar_type());
  model_->begin(K, s0.reshape({n}));

  dispatch_floating(plan_, [&](auto tag) {
    using T = decltype(tag);
    // Warm start: the previous plan moved one step earlier, a zero action appended.
    auto plan = row_map<T>(plan_);
    if (H > 1) plan.topRows(H - 1) = plan.bottomRows(H - 1).eval();
    plan.row(H - 1).setZero();
    Eigen::Map<const Eigen::Matrix<T, 1, Eigen::Dynamic>> s(s0.data_ptr<T>(), n);
    row_map<T>(states_a_).rowwise() = s;
  });

  // All K rollouts advance together: per step one sampler call and one model step on [K, .] batches.
  sampler_->begin(K, plan_);
  at::Tensor* s = &states_a_;
  at::Tensor* s_next = &states_b_;
  for (int64_t t = 0; t < H; ++t) {
    sampler_->sample(t, *s, plan_rows_[t], sample_rows_[t]);
    model_->step(*s, sample_rows_[t], *s_next, reward_rows_[t]);
    std::swap(s, s_next);
  }
  const bool tail = options_.terminal_value_weight > 0;
  if (tail) {
    // *s is s_H, the last predicted state of every sample.
    terminal_values_ = terminal_value_(*s).reshape({-1}).to(plan_.scalar_type()).contiguous();
    check(terminal_values_.numel() == K, "{}: the terminal value gave {} values for {} states", name_,
          terminal_values_.numel(), K);
  }
  // The samples' log-density is only computed where the weights use it.
  if (options_.density_in_weights) log_density_ = sampler_->log_density(samples_);

  bool finite = true;
  dispatch_floating(plan_, [&](auto tag) {
    using T = decltype(tag);
    // J_t^k: the predicted reward to go from step t.
    RowMatrix<T> J = row_map<T>(rewards_);
    for (int64_t t = H - 2; t >= 0; --t)
      J.row(t) += J.row(t + 1);
    if (tail) {
      Eigen::Map<const Eigen::Matrix<T, 1, Eigen::Dynamic>> v(terminal_values_.data_ptr<T>(), K);
      J.rowwise() += T(options_.terminal_value_weight) * v;
    }
    // log w = J / lambda (+ log p(v)); normalise in log space: subtracting each step's max keeps exp() in
    // range.
    const RowMatrix<T> scaled = J / T(options_.lambda);
    RowMatrix<T> density;
    if (options_.density_in_weights) density = row_map<T>(log_density_);
    auto w = row_map<T>(weights_);
    w = planner_weights<T>(scaled, options_.density_in_weights ? &density : nullptr, options_.weight_floor,
                           options_.min_ess);
    auto plan = row_map<T>(plan_);
    Eigen::Map<const RowMatrix<T>> all_samples(samples_.data_ptr<T>(), H * K, m);
    const bool all_finite = all_samples.allFinite();
    // dst += sum_k w_t^k x^k over the rows of x [K, m]. A diverged rollout's later actions are NaN (drawn at
    // NaN states) and its weight is 0: leave it out rather than let 0 x NaN through. Rows with no finite
    // weight stay NaN (the fallback).
    auto add_weighted = [&](int64_t t, const auto& x, auto&& dst) {
      if (all_finite) {
        dst += w.row(t) * x;
        return;
      }
      Eigen::Matrix<T, 1, Eigen::Dynamic> step = Eigen::Matrix<T, 1, Eigen::Dynamic>::Zero(m);
      for (int64_t k = 0; k < K; ++k)
        if (w(t, k) != T(0)) step += w(t, k) * x.row(k);  // NaN != 0: kept
      dst += step;
    };
    for (int64_t t = 0; t < H; ++t) {
      Eigen::Map<const RowMatrix<T>> v(samples_.data_ptr<T>() + t * K * m, K, m);
      if (options_.average_before_squash) {
        // a_t = tanh(sum_k w_t^k atanh(v_t^k))
        const RowMatrix<T> u = clipped_atanh(v.array()).matrix();
        Eigen::Matrix<T, 1, Eigen::Dynamic> mean = Eigen::Matrix<T, 1, Eigen::Dynamic>::Zero(m);
        add_weighted(t, u, mean);
        plan.row(t) = mean.array().tanh().matrix();
      } else {
        // a_t += sum_k w_t^k (v_t^k - a_t)
        add_weighted(t, v.rowwise() - plan.row(t), plan.row(t));
      }
    }
    finite = plan.allFinite();
    // Diagnostics of step 0's weights: effective sample size and the weight on saturated actions.
    diagnostics_.weight_ess = 1.0 / static_cast<double>(w.row(0).squaredNorm());
    Eigen::Map<const RowMatrix<T>> v0(samples_.data_ptr<T>(), K, m);
    const Eigen::Matrix<T, Eigen::Dynamic, 1> max_abs = v0.array().abs().rowwise().maxCoeff();
    diagnostics_.saturated_weight =
        static_cast<double>((max_abs.array() > T(0.99)).select(w.row(0).transpose().array(), T(0)).sum());
  });
  at::Tensor action = plan_rows_[0].clone();
  // Do not carry a poisoned plan into the next step; the base class substitutes the fallback action.
  if (!finite) plan_.zero_();
  return action;
}

}  // namespace hlt
