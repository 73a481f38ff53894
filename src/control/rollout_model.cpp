#include "hlt/control/rollout_model.h"

#include <ATen/core/grad_mode.h>

#include "hlt/util/error.h"

namespace hlt {

void clamp_rows(at::Tensor& rows, const at::Tensor& low, const at::Tensor& high) {
  check(rows.dim() == 2 && low.dim() == 1 && high.dim() == 1 && low.size(0) == rows.size(1) &&
            high.size(0) == rows.size(1) && low.scalar_type() == rows.scalar_type() &&
            high.scalar_type() == rows.scalar_type(),
        "clamp_rows: bounds must be [{}] of the rows' dtype", rows.dim() == 2 ? rows.size(1) : -1);
  dispatch_floating(rows, [&](auto tag) {
    using T = decltype(tag);
    const int64_t n = rows.size(1);
    Eigen::Map<const Eigen::Array<T, 1, Eigen::Dynamic>> lo(low.data_ptr<T>(), n), hi(high.data_ptr<T>(), n);
    auto r = row_map<T>(rows);
    for (Eigen::Index i = 0; i < r.rows(); ++i)
      r.row(i) = r.row(i).array().max(lo).min(hi).matrix();
  });
}

LearnedRolloutModel::LearnedRolloutModel(DynamicsModel dynamics, RewardModel reward, bool clamp_to_domain)
    : dynamics_(dynamics),
      reward_(reward),
      forward_(std::move(dynamics), std::move(reward)),
      clamp_to_domain_(clamp_to_domain) {}

void LearnedRolloutModel::begin(int64_t batch, const at::Tensor&) {
  forward_.prepare(batch);
}

void LearnedRolloutModel::step(const at::Tensor& states, const at::Tensor& actions, at::Tensor& next_states,
                               at::Tensor& rewards) {
  const bool next_state_reward = reward_->options().reads_next_state;
  forward_.step(states, actions, next_states, next_state_reward ? nullptr : &rewards);
  if (clamp_to_domain_ && dynamics_->has_domain())
    clamp_rows(next_states, dynamics_->domain_low(), dynamics_->domain_high());
  // A reward of the reached state scores the state the rollout goes on from (after the clamp).
  if (next_state_reward) {
    at::NoGradGuard no_grad;
    rewards.copy_(reward_->forward(next_states, actions).reshape(rewards.sizes()));
  }
}

}  // namespace hlt
