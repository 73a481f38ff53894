// hlt::StochasticHybrid: the paper's Alg. 2 (Theorem 2). A warm-started action plan a_0..a_{H-1} is improved
// each step by K rollouts of the learned dynamics and reward models with actions drawn from an
// ActionSampler, weighted per time step by exp(J_t / lambda) p(v_t) (J_t the predicted reward-to-go), then
// a_0 is applied. With a PolicySampler this is hybrid learning; with a FilteredNoiseSampler it is the
// NN-MPPI baseline. All K samples move through each step as one batch of tensor operations.
#pragma once

#include <memory>
#include <vector>

#include "hlt/control/action_sampler.h"
#include "hlt/control/controller.h"
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
};

class StochasticHybrid : public Controller {
 public:
  StochasticHybrid(std::shared_ptr<ActionSampler> sampler, DynamicsModel dynamics, RewardModel reward,
                   const StochasticHybridOptions& options, GaussianPolicy fallback_policy = nullptr,
                   std::string name = "stochastic_hybrid");

  std::string name() const override { return name_; }
  void reset() override;
  // The current plan [H, m] (after the last call's update).
  const at::Tensor& plan() const { return plan_; }
  // The last call's weights [H, K], sampled actions [H, K, m] and their log-densities [H, K] (computed
  // only with density_in_weights; undefined otherwise).
  const at::Tensor& weights() const { return weights_; }
  at::Tensor samples() const { return samples_.permute({0, 2, 1}); }
  const at::Tensor& log_density() const { return log_density_; }

 protected:
  at::Tensor compute_action(const at::Tensor& state) override;

 private:
  std::shared_ptr<ActionSampler> sampler_;
  DynamicsModel dynamics_;
  ModelForward models_;
  StochasticHybridOptions options_;
  std::string name_;
  at::Tensor plan_, weights_, samples_, log_density_, rewards_;
  at::Tensor states_a_, states_b_;  // rollout state buffers [n, K] (feature-major)
  std::vector<at::Tensor> plan_rows_, sample_rows_, reward_rows_;  // per-step views
};

}  // namespace hlt
