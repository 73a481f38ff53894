#include "envs/env.h"

#include <cmath>

#include "hlt/util/error.h"

namespace hlt {

Eigen::VectorXd Env::reset(std::optional<uint64_t> seed) {
  if (seed) rng_.seed(*seed);
  Eigen::VectorXd obs = reset_impl(rng_);
  check(obs.size() == observation_dim(), "{}: reset returned {} values, expected {}", name(), obs.size(),
        observation_dim());
  check(obs.allFinite(), "{}: initial observation is not finite", name());
  elapsed_ = 0;
  needs_reset_ = false;
  last_observation_ = obs;
  return obs;
}

StepResult Env::step(const Eigen::VectorXd& action) {
  check(!needs_reset_, "{}: step() called before reset() or after the episode ended", name());
  check(action.size() == action_dim(), "{}: action has {} values, expected {}", name(), action.size(),
        action_dim());
  check(action.allFinite(), "{}: action contains NaN or Inf", name());
  StepResult r = step_impl(action);
  ++elapsed_;
  if (r.observation.size() != observation_dim() || !r.observation.allFinite() || !std::isfinite(r.reward)) {
    // A simulation that blew up ends the episode; the agent never sees the non-finite values.
    if (r.failure.empty())
      r.failure = fmt::format("{}: simulation became non-finite at step {}", name(), elapsed_);
    r.observation = last_observation_;
    r.reward = 0.0;
    r.terminated = true;
  }
  if (elapsed_ >= max_episode_steps()) r.truncated = true;
  last_observation_ = r.observation;
  if (r.done()) needs_reset_ = true;
  return r;
}

EnvState Env::save_state() const {
  EnvState s;
  s.sim = save_sim();
  s.rng = rng_;
  s.elapsed_steps = elapsed_;
  s.needs_reset = needs_reset_;
  s.last_observation = last_observation_;
  save_wrapped(s);
  return s;
}

void Env::restore_state(const EnvState& s) {
  restore_sim(s.sim);
  restore_wrapped(s);
  rng_ = s.rng;
  elapsed_ = s.elapsed_steps;
  needs_reset_ = s.needs_reset;
  last_observation_ = s.last_observation;
}

FrameSkip::FrameSkip(std::unique_ptr<Env> inner, int k) : inner_(std::move(inner)), k_(k) {
  check(inner_ != nullptr, "FrameSkip needs an environment");
  check(k >= 1, "frame skip must be >= 1, got {}", k);
}

Eigen::VectorXd FrameSkip::reset_impl(std::mt19937_64& rng) {
  return inner_->reset(rng());
}

StepResult FrameSkip::step_impl(const Eigen::VectorXd& action) {
  StepResult total;
  last_frames_ = 0;
  for (int i = 0; i < k_; ++i) {
    StepResult r = inner_->step(action);
    ++last_frames_;
    total.reward += r.reward;
    total.observation = std::move(r.observation);
    total.terminated = r.terminated;
    total.truncated = r.truncated;
    total.failure = r.failure;
    if (r.done()) break;
  }
  return total;
}

void FrameSkip::save_wrapped(EnvState& state) const { state.wrapped = {inner_->save_state()}; }

void FrameSkip::restore_wrapped(const EnvState& state) {
  check(state.wrapped.size() == 1, "{}: snapshot does not hold the wrapped environment", name());
  inner_->restore_state(state.wrapped.front());
}

}  // namespace hlt
