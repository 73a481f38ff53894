#include "hlt/control/rollout_model.h"

#include <ATen/ATen.h>
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

LearnedRolloutModel::LearnedRolloutModel(DynamicsModel dynamics, RewardModel reward, bool clamp_to_domain,
                                         EnsembleOptions ensemble)
    : dynamics_(dynamics),
      reward_(reward),
      forward_(std::move(dynamics), std::move(reward)),
      clamp_to_domain_(clamp_to_domain),
      ensemble_(std::move(ensemble)) {
  check(ensemble_.disagreement_penalty >= 0, "the ensemble's disagreement penalty must be >= 0, got {}",
        ensemble_.disagreement_penalty);
  check(ensemble_.disagreement_penalty == 0 || !ensemble_.members.empty(),
        "a disagreement penalty needs an ensemble of at least two dynamics models (model.ensemble > 1)");
  for (const DynamicsModel& m : ensemble_.members) {
    check(!m.is_empty() && m->options().state_dim == dynamics_->options().state_dim &&
              m->options().action_dim == dynamics_->options().action_dim &&
              m->fc1->weight.scalar_type() == dtype(),
          "every ensemble member must be a dynamics model of the first one's sizes and dtype");
  }
}

void LearnedRolloutModel::begin(int64_t batch, const at::Tensor&) {
  forward_.prepare(batch);
}

void LearnedRolloutModel::step(const at::Tensor& states, const at::Tensor& actions, at::Tensor& next_states,
                               at::Tensor& rewards) {
  const bool next_state_reward = reward_->options().reads_next_state;
  forward_.step(states, actions, next_states, next_state_reward ? nullptr : &rewards);
  if (!ensemble_.members.empty()) {
    at::NoGradGuard no_grad;
    // [N, B, n]: the first member's prediction (the fused pass's) and the others'.
    std::vector<at::Tensor> predictions{next_states};
    for (DynamicsModel& m : ensemble_.members)
      predictions.push_back(m->forward(states, actions));
    const at::Tensor all = at::stack(predictions);
    const at::Tensor mean = all.mean(0);
    if (ensemble_.disagreement_penalty > 0) {
      const at::Tensor variance = (all - mean).square().mean(0);     // [B, n]
      const at::Tensor noise = at::exp(2.0 * dynamics_->log_std());  // [1, n]
      const at::Tensor u = (variance / noise).mean(-1).sqrt();       // [B]
      if (!next_state_reward) rewards.sub_(u.reshape(rewards.sizes()), ensemble_.disagreement_penalty);
      penalty_ = u;
    }
    next_states.copy_(mean);
  }
  if (clamp_to_domain_ && dynamics_->has_domain())
    clamp_rows(next_states, dynamics_->domain_low(), dynamics_->domain_high());
  // A reward of the reached state scores the state the rollout goes on from (after the clamp).
  if (next_state_reward) {
    at::NoGradGuard no_grad;
    rewards.copy_(reward_->forward(next_states, actions).reshape(rewards.sizes()));
    if (ensemble_.disagreement_penalty > 0)
      rewards.sub_(penalty_.reshape(rewards.sizes()), ensemble_.disagreement_penalty);
  }
}

}  // namespace hlt
