#include "hlt/control/action_sampler.h"

#include <cmath>

#include <torch/torch.h>

#include "hlt/util/error.h"

namespace hlt {
namespace {

const double kHalfLog2Pi = 0.5 * std::log(2.0 * M_PI);

// The [rows, cols] block that starts `offset` elements into a contiguous tensor.
template <typename T>
Eigen::Map<RowMatrix<T>> block(const at::Tensor& t, int64_t offset, int64_t rows, int64_t cols) {
  return Eigen::Map<RowMatrix<T>>(t.data_ptr<T>() + offset, rows, cols);
}

}  // namespace

PolicySampler::PolicySampler(GaussianPolicy policy, bool tanh_correction, bool mean_rollout)
    : forward_(std::move(policy)), tanh_correction_(tanh_correction), mean_rollout_(mean_rollout) {}

void PolicySampler::begin(int64_t samples, const at::Tensor& plan) {
  forward_.prepare(samples);
  eps_ = torch::randn({plan.size(0), samples, plan.size(1)}, plan.options());
  // Drawn and then zeroed, so that the other rollouts see the same random numbers either way.
  if (mean_rollout_) eps_.select(1, 0).zero_();
  if (!log_std_.defined() || log_std_.sizes() != eps_.sizes() ||
      log_std_.scalar_type() != eps_.scalar_type()) {
    log_std_ = torch::empty_like(eps_);
  }
}

void PolicySampler::sample(int64_t t, const at::Tensor& states, const at::Tensor& plan_t,
                           at::Tensor& actions) {
  forward_.forward(states);
  dispatch_floating(actions, [&](auto tag) {
    using T = decltype(tag);
    const int64_t K = actions.size(0), m = actions.size(1);
    const auto mean = row_map<T>(forward_.mean()).array();
    const auto ls = row_map<T>(forward_.log_std()).array();
    block<T>(log_std_, t * K * m, K, m) = ls.matrix();
    // v = tanh(mu + sigma eps)
    row_map<T>(actions) = (mean + ls.exp() * block<T>(eps_, t * K * m, K, m).array()).tanh().matrix();
  });
}

at::Tensor PolicySampler::log_density(const at::Tensor& actions) {
  const int64_t H = actions.size(0), K = actions.size(1), m = actions.size(2);
  at::Tensor out = torch::empty({H, K}, actions.options());
  dispatch_floating(actions, [&](auto tag) {
    using T = decltype(tag);
    for (int64_t t = 0; t < H; ++t) {
      const auto eps = block<T>(eps_, t * K * m, K, m).array(),
                 ls = block<T>(log_std_, t * K * m, K, m).array(),
                 v = block<T>(actions, t * K * m, K, m).array();
      // u - mu = sigma eps, so the Gaussian term is -eps^2 / 2 - log sigma - log(2 pi) / 2 per dimension; the
      // tanh change of variables (if asked for) subtracts log(1 - v^2 + 1e-6).
      const auto gauss = T(-0.5) * eps.square() - ls - T(kHalfLog2Pi);
      if (tanh_correction_) {
        block<T>(out, t * K, 1, K) =
            (gauss - (T(1 + 1e-6) - v.square()).log()).rowwise().sum().matrix().transpose();
      } else {
        block<T>(out, t * K, 1, K) = gauss.rowwise().sum().matrix().transpose();
      }
    }
  });
  return out;
}

FilteredNoiseSampler::FilteredNoiseSampler(double sigma, double filter, std::optional<GaussianPolicy> scale)
    : sigma_(sigma), filter_(filter) {
  check(sigma > 0, "MPPI noise sigma must be > 0, got {}", sigma);
  check(filter >= 0 && filter < 1, "MPPI filter must be in [0, 1), got {}", filter);
  if (scale) scale_.emplace(std::move(*scale));
}

void FilteredNoiseSampler::begin(int64_t samples, const at::Tensor& plan) {
  z_ = torch::randn({plan.size(0), samples, plan.size(1)}, plan.options());
  if (!eta_.defined() || eta_.size(0) != samples || eta_.scalar_type() != plan.scalar_type()) {
    eta_ = torch::empty({samples, plan.size(1)}, plan.options());
  }
  dispatch_floating(eta_, [&](auto tag) {
    using T = decltype(tag);
    row_map<T>(eta_).setZero();
  });
  if (scale_) {
    scale_->prepare(samples);
    if (!sigmas_.defined() || sigmas_.sizes() != z_.sizes() || sigmas_.scalar_type() != z_.scalar_type())
      sigmas_ = torch::empty_like(z_);
  }
}

void FilteredNoiseSampler::sample(int64_t t, const at::Tensor& states, const at::Tensor& plan_t,
                                  at::Tensor& actions) {
  if (scale_) scale_->forward(states);
  dispatch_floating(actions, [&](auto tag) {
    using T = decltype(tag);
    const int64_t K = actions.size(0), m = actions.size(1);
    auto eta = row_map<T>(eta_);
    Eigen::Map<const Eigen::Matrix<T, 1, Eigen::Dynamic>> a(plan_t.data_ptr<T>(), m);
    const auto z = block<T>(z_, t * K * m, K, m).array();
    if (scale_) {
      auto sig = block<T>(sigmas_, t * K * m, K, m);
      sig = row_map<T>(scale_->log_std()).array().exp().min(T(sigma_)).matrix();
      eta = (T(filter_) * eta.array() + T(1.0 - filter_) * sig.array() * z).matrix();
    } else {
      eta = (T(filter_) * eta.array() + T((1.0 - filter_) * sigma_) * z).matrix();
    }
    row_map<T>(actions) = (eta.rowwise() + a).array().max(T(-1)).min(T(1)).matrix();
  });
}

at::Tensor FilteredNoiseSampler::log_density(const at::Tensor& actions) {
  const int64_t H = actions.size(0), K = actions.size(1), m = actions.size(2);
  at::Tensor out = torch::empty({H, K}, actions.options());
  dispatch_floating(actions, [&](auto tag) {
    using T = decltype(tag);
    for (int64_t t = 0; t < H; ++t) {
      const auto z2 = block<T>(z_, t * K * m, K, m).array().square();
      if (scale_) {
        const auto sig = block<T>(sigmas_, t * K * m, K, m).array();
        block<T>(out, t * K, 1, K) =
            (T(-0.5) * z2 - sig.log() - T(kHalfLog2Pi)).rowwise().sum().matrix().transpose();
      } else {
        block<T>(out, t * K, 1, K) =
            (T(-0.5) * z2 - T(std::log(sigma_) + kHalfLog2Pi)).rowwise().sum().matrix().transpose();
      }
    }
  });
  return out;
}

MixtureSampler::MixtureSampler(std::shared_ptr<ActionSampler> first, std::shared_ptr<ActionSampler> second,
                               int64_t second_samples, GaussianPolicy prior, bool tanh_correction)
    : first_(std::move(first)),
      second_(std::move(second)),
      second_samples_(second_samples),
      prior_(std::move(prior)),
      tanh_correction_(tanh_correction) {
  check(first_ && second_, "mixture sampler: needs two samplers");
  check(second_samples >= 1, "mixture sampler: second_samples must be >= 1, got {}", second_samples);
}

void MixtureSampler::begin(int64_t samples, const at::Tensor& plan) {
  check(samples > second_samples_, "mixture sampler: {} samples, {} of them for the second sampler", samples,
        second_samples_);
  first_samples_ = samples - second_samples_;
  first_->begin(first_samples_, plan);
  second_->begin(second_samples_, plan);
  const int64_t m = plan.size(1);
  if (!actions_first_.defined() || actions_first_.size(0) != first_samples_ || actions_first_.size(1) != m ||
      actions_first_.scalar_type() != plan.scalar_type()) {
    actions_first_ = torch::empty({first_samples_, m}, plan.options());
    actions_second_ = torch::empty({second_samples_, m}, plan.options());
  }
  horizon_ = plan.size(0);
}

void MixtureSampler::sample(int64_t t, const at::Tensor& states, const at::Tensor& plan_t,
                            at::Tensor& actions) {
  // Sample-major batches: each proposal's rollouts are a contiguous block of rows.
  const at::Tensor s1 = states.narrow(0, 0, first_samples_);
  const at::Tensor s2 = states.narrow(0, first_samples_, second_samples_);
  first_->sample(t, s1, plan_t, actions_first_);
  second_->sample(t, s2, plan_t, actions_second_);
  actions.narrow(0, 0, first_samples_).copy_(actions_first_);
  actions.narrow(0, first_samples_, second_samples_).copy_(actions_second_);
  // Kept for the prior in log_density().
  const int64_t K = states.size(0);
  if (!states_.defined() || states_.size(1) != states.size(1) || states_.size(0) != horizon_ * K ||
      states_.scalar_type() != states.scalar_type()) {
    states_ = torch::empty({horizon_ * K, states.size(1)}, states.options());
  }
  states_.narrow(0, t * K, K).copy_(states);
}

at::Tensor MixtureSampler::log_density(const at::Tensor& actions) {
  const int64_t H = actions.size(0), K = actions.size(1), m = actions.size(2);
  check(states_.defined() && states_.size(0) == H * K,
        "mixture sampler: log_density before a full sampling pass");
  // The prior at every rollout state of every step in one pass: rows t K ... t K + K - 1 are step t's.
  prior_.prepare(H * K);
  prior_.forward(states_);
  at::Tensor out = torch::empty({H, K}, actions.options());
  dispatch_floating(actions, [&](auto tag) {
    using T = decltype(tag);
    const T edge = T(1) - T(1e-6);
    for (int64_t t = 0; t < H; ++t) {
      const auto v = block<T>(actions, t * K * m, K, m).array().max(-edge).min(edge);
      const auto mu = row_map<T>(prior_.mean()).middleRows(t * K, K).array(),
                 ls = row_map<T>(prior_.log_std()).middleRows(t * K, K).array();
      const auto u = clipped_atanh(v);
      const auto gauss = T(-0.5) * ((u - mu) * (-ls).exp()).square() - ls - T(kHalfLog2Pi);
      if (tanh_correction_) {
        block<T>(out, t * K, 1, K) =
            (gauss - (T(1 + 1e-6) - v.square()).log()).rowwise().sum().matrix().transpose();
      } else {
        block<T>(out, t * K, 1, K) = gauss.rowwise().sum().matrix().transpose();
      }
    }
  });
  return out;
}

}  // namespace hlt
