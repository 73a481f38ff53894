// PlanCheck (agents/plan_check.h): the planner's samples replayed on the simulator. The rank correlation must
// be the textbook one (ties included); a planner on a perfect model must rank its samples exactly as the
// replay does and pick above their average; one on a model whose rewards are negated must rank them in
// reverse and pick below; the check must leave the environment where it was.
#include <gtest/gtest.h>

#include <cmath>

#include <torch/torch.h>

#include "agents/controller_policy.h"
#include "agents/methods.h"
#include "agents/plan_check.h"
#include "agents/simulator_model.h"
#include "agents/train_config.h"
#include "envs/registry.h"
#include "hlt/util/error.h"
#include "support/planner_setup.h"

namespace hlt {
namespace {

TEST(Spearman, MatchesHandComputedValues) {
  EXPECT_DOUBLE_EQ(spearman({1, 2, 3, 4}, {10, 20, 35, 40}), 1.0);
  EXPECT_DOUBLE_EQ(spearman({1, 2, 3, 4}, {4, 3, 2, 1}), -1.0);
  // Ties share their mean rank: ranks (0, 1.5, 1.5, 3) against (0, 1, 2, 3) give 4.5 / sqrt(4.5 * 5).
  EXPECT_NEAR(spearman({1, 2, 2, 3}, {1, 2, 3, 4}), 4.5 / std::sqrt(22.5), 1e-12);
  // Monotone transformations do not change ranks: (3, 1, 2) against (30, -5, 7).
  EXPECT_DOUBLE_EQ(spearman({3, 1, 2}, {30, -5, 7}), 1.0);
  EXPECT_TRUE(std::isnan(spearman({1, 1, 1}, {1, 2, 3})));  // no spread
  EXPECT_TRUE(std::isnan(spearman({1, 2}, {1, 2, 3})));     // sizes differ
  EXPECT_TRUE(std::isnan(spearman({1}, {1})));
}

// The simulator with every reward negated: a model that ranks every sample in reverse.
class NegatedSimulator : public RolloutModel {
 public:
  explicit NegatedSimulator(const Env& env) : sim_(env, at::kFloat) {}
  int64_t state_dim() const override { return sim_.state_dim(); }
  int64_t action_dim() const override { return sim_.action_dim(); }
  at::ScalarType dtype() const override { return sim_.dtype(); }
  void begin(int64_t batch, const at::Tensor& start) override { sim_.begin(batch, start); }
  void step(const at::Tensor& states, const at::Tensor& actions, at::Tensor& next_states,
            at::Tensor& rewards) override {
    sim_.step(states, actions, next_states, rewards);
    rewards.neg_();
  }

 private:
  SimulatorRolloutModel sim_;
};

TEST(PlanCheck, APerfectModelRanksItsSamplesAsTheReplayAndAReversedOneInReverse) {
  auto env = make_env("pendulum");
  const Eigen::VectorXd o = env->reset(3);
  for (const bool negated : {false, true}) {
    torch::manual_seed(0);
    const Config config = testing::planner_config(10, 20, 1.0);
    std::shared_ptr<RolloutModel> model;
    if (negated)
      model = std::make_shared<NegatedSimulator>(*env);
    else
      model = std::make_shared<SimulatorRolloutModel>(*env, at::kFloat);
    const LearnedModels models = testing::untrained_policy_planning_on(*env, model);
    std::unique_ptr<Controller> controller = make_controller("stochastic_hybrid", models, config, true);
    const auto* planner = dynamic_cast<const StochasticHybrid*>(controller.get());
    ASSERT_NE(planner, nullptr);
    PlanCheck check(*env, nullptr);
    EXPECT_THROW(check.add(*planner), Error);  // no planning call yet
    controller->reset();
    ControllerPolicy acting(*controller);
    acting.act(o);
    const EnvState before = env->save_state();
    const PlanCheckCall c = check.add(*planner);
    const EnvState after = env->save_state();
    EXPECT_EQ(after.sim, before.sim) << "the check moved the environment";
    EXPECT_EQ(after.elapsed_steps, before.elapsed_steps);
    EXPECT_EQ(after.rng, before.rng);
    EXPECT_GT(c.spread, 0);
    EXPECT_TRUE(std::isnan(c.rank_reward));  // no learned reward model given
    if (negated) {
      EXPECT_LT(c.rank_models, -0.999);
      EXPECT_LT(c.selection, 0);
    } else {
      EXPECT_GT(c.rank_models, 0.999);
      EXPECT_GT(c.selection, 0.3);
      EXPECT_LE(c.selection, 1.0 + 1e-9);
    }
    ASSERT_EQ(check.calls().size(), 1u);
    EXPECT_NE(check.summary().find("over 1 planning calls"), std::string::npos);
  }
}

}  // namespace
}  // namespace hlt
