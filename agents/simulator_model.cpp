#include "agents/simulator_model.h"

#include <vector>

#include <torch/torch.h>

#include "envs/registry.h"
#include "hlt/util/error.h"

namespace hlt {

SimulatorRolloutModel::SimulatorRolloutModel(const Env& env, at::ScalarType dtype, RewardModel reward)
    : env_(env), sim_(make_env_like(env)), dtype_(dtype), reward_(std::move(reward)) {
  check(dtype == at::kFloat || dtype == at::kDouble, "SimulatorRolloutModel: dtype must be float or double");
  check(reward_.is_empty() || (reward_->options().state_dim == env.observation_dim() &&
                               reward_->options().action_dim == env.action_dim()),
        "SimulatorRolloutModel: the reward model's sizes are not {}'s", env.name());
}

void SimulatorRolloutModel::begin(int64_t batch, const at::Tensor& start) {
  check(start.numel() == env_.observation_dim(),
        "SimulatorRolloutModel: a start state of {} values, {} has {}", start.numel(), env_.name(),
        env_.observation_dim());
  snapshots_.assign(static_cast<size_t>(batch), env_.save_state());
  ended_.assign(static_cast<size_t>(batch), false);
}

void SimulatorRolloutModel::step(const at::Tensor& states, const at::Tensor& actions, at::Tensor& next_states,
                                 at::Tensor& rewards) {
  const int64_t K = states.size(0), n = state_dim(), m = action_dim();
  check(static_cast<size_t>(K) == snapshots_.size() && actions.size(0) == K && actions.size(1) == m &&
            next_states.size(0) == K && next_states.size(1) == n && rewards.numel() == K,
        "SimulatorRolloutModel: a step of {} rollouts after begin() with {}", K, snapshots_.size());
  // Through doubles: the environments' own type.
  const at::Tensor s = states.to(at::kDouble).contiguous(), a = actions.to(at::kDouble).contiguous();
  at::Tensor next = torch::empty({K, n}, s.options()), r = torch::zeros({K}, s.options());
  // A learned reward scores each live rollout's step, from the state it starts in or (r(s', a) models) the
  // one it reaches; a rollout that has ended earns nothing more.
  const std::vector<bool> ended_before = ended_;
  for (int64_t k = 0; k < K; ++k) {
    const size_t i = static_cast<size_t>(k);
    Eigen::Map<Eigen::VectorXd> next_k(next.data_ptr<double>() + k * n, n);
    if (ended_[i]) {
      next_k = Eigen::Map<const Eigen::VectorXd>(s.data_ptr<double>() + k * n, n);
      continue;
    }
    sim_->restore_state(snapshots_[i]);
    const StepResult result = sim_->step(Eigen::Map<const Eigen::VectorXd>(a.data_ptr<double>() + k * m, m));
    next_k = result.observation;
    r.data_ptr<double>()[k] = result.reward;
    snapshots_[i] = sim_->save_state();
    ended_[i] = result.done();
  }
  if (!reward_.is_empty()) {
    const auto dtype = reward_->parameters().front().scalar_type();
    const at::Tensor learned = reward_->predict(states.to(dtype), actions.to(dtype), next.to(dtype))
                                   .reshape({K})
                                   .to(at::kDouble)
                                   .contiguous();
    for (int64_t k = 0; k < K; ++k)
      r.data_ptr<double>()[k] = ended_before[static_cast<size_t>(k)] ? 0.0 : learned.data_ptr<double>()[k];
  }
  next_states.copy_(next);
  rewards.copy_(r.reshape(rewards.sizes()));
}

}  // namespace hlt
