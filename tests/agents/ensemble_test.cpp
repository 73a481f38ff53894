// The dynamics ensemble (model.ensemble, planner.disagreement_penalty). The learner must train each member
// exactly as a lone model learner trains it (no cross-talk through the shared optimizer) and log the
// members' mean loss; the rollout model must predict the members' mean and take the penalty, computed by
// hand here, off every step's reward; the members must go through checkpoints; and the controllers that
// cannot use an ensemble, or a penalty without one, must refuse.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>
#include <filesystem>

#include "agents/learner.h"
#include "agents/model_learner.h"
#include "agents/train_config.h"
#include "hlt/control/rollout_model.h"
#include "hlt/core/checkpoint.h"
#include "hlt/data/replay_buffer.h"
#include "hlt/util/error.h"
#include "support/error_of.h"
#include "support/random_transitions.h"

namespace hlt {
namespace {

constexpr int64_t kN = 3, kM = 2;

ReplayBuffer random_buffer(uint64_t seed) {
  return testing::random_transitions(kN, kM, seed);
}

// A network of the same options holding the same values.
template <typename Module>
Module copy_of(const Module& m) {
  Module c(m->options());
  c->to(m->parameters().front().scalar_type());
  torch::NoGradGuard g;
  const auto from = m->parameters(), to = c->parameters();
  for (size_t k = 0; k < from.size(); ++k)
    to[k].copy_(from[k]);
  return c;
}

TEST(Ensemble, EachMemberTrainsAsALoneModelAndTheLossIsTheMembersMean) {
  torch::manual_seed(1);
  const DynamicsModelOptions o{kN, kM, 16, Activation::kSin};
  DynamicsModel first(o), second(o), third(o);
  RewardModel reward(RewardModelOptions{kN, kM, 8});
  // The same networks, each trained by a lone learner.
  DynamicsModel lone_second = copy_of(second), lone_third = copy_of(third);
  RewardModel reward_second = copy_of(reward), reward_third = copy_of(reward);
  ModelLearnerOptions lo;
  ModelLearner ensemble(first, reward, lo, {second, third});
  ModelLearner alone_second(lone_second, reward_second, lo), alone_third(lone_third, reward_third, lo);
  ASSERT_FALSE(torch::equal(first->fc1->weight, second->fc1->weight));  // own initial weights

  ReplayBuffer buffer = random_buffer(3);
  for (int i = 0; i < 4; ++i) {
    const Batch b = buffer.sample(16);
    const double expected = (first->loss(b.states, b.actions, b.next_states).item<double>() +
                             second->loss(b.states, b.actions, b.next_states).item<double>() +
                             third->loss(b.states, b.actions, b.next_states).item<double>()) /
                            3.0;
    const ModelLosses l = ensemble.update(b);
    alone_second.update(b);
    alone_third.update(b);
    EXPECT_NEAR(l.dynamics, expected, 1e-5 * std::abs(expected) + 1e-6) << "update " << i;
  }
  for (auto [member, lone] : {std::pair{second, lone_second}, std::pair{third, lone_third}}) {
    const auto p = member->parameters(), q = lone->parameters();
    ASSERT_EQ(p.size(), q.size());
    for (size_t k = 0; k < p.size(); ++k)
      EXPECT_TRUE(torch::equal(p[k], q[k])) << "parameter " << k;
  }
}

TEST(Ensemble, TheLearnerBuildsTheMembersAndTheyGoThroughACheckpoint) {
  Config c = make_train_config();
  for (const char* kv : {"model.hidden=8", "model.reward_hidden=8", "model.ensemble=3"})
    c.apply_override(kv);
  const std::string path = (std::filesystem::temp_directory_path() / "hlt_ensemble_test.pt").string();
  torch::manual_seed(3);
  LearnedModels models;
  LearnerContext context{c, kN, kM, 11, models};
  auto learner = make_learner("models", context);
  ASSERT_EQ(models.ensemble.size(), 2u);
  ReplayBuffer buffer = random_buffer(5);
  learner->train(buffer.sample(16));
  auto* model_learner = dynamic_cast<ModelLearner*>(learner.get());
  ASSERT_NE(model_learner, nullptr);
  CheckpointWriter w;
  model_learner->save(w);
  w.save(path);
  const Batch next = buffer.sample(16);
  const NamedLosses first = learner->train(next);

  torch::manual_seed(99);
  LearnedModels other;
  LearnerContext other_context{c, kN, kM, 12, other};
  auto resumed = make_learner("models", other_context);
  ASSERT_FALSE(torch::equal(other.ensemble[1]->fc1->weight, models.ensemble[1]->fc1->weight));
  CheckpointReader r(path);
  dynamic_cast<ModelLearner*>(resumed.get())->load(r);
  const NamedLosses second = resumed->train(next);
  ASSERT_EQ(first.size(), second.size());
  for (size_t k = 0; k < first.size(); ++k)
    EXPECT_EQ(first[k].value, second[k].value) << first[k].tag;
  for (size_t i = 0; i < 2; ++i)
    EXPECT_TRUE(torch::equal(other.ensemble[i]->fc2->weight, models.ensemble[i]->fc2->weight)) << i;
  const auto named = named_dynamics(models.dynamics, models.ensemble);
  ASSERT_EQ(named.size(), 3u);
  EXPECT_EQ(named[0].first, "dynamics");
  EXPECT_EQ(named[1].first, "dynamics_member1");
  EXPECT_EQ(named[2].first, "dynamics_member2");
  EXPECT_TRUE(named_dynamics(DynamicsModel(nullptr), {}).empty());
  std::filesystem::remove(path);
}

TEST(Ensemble, TheRolloutModelPredictsTheMembersMeanAndPenalisesTheirDisagreement) {
  torch::manual_seed(2);
  const DynamicsModelOptions o{kN, kM, 16, Activation::kSin};
  DynamicsModel first(o), second(o), third(o);
  RewardModel reward(RewardModelOptions{kN, kM, 8});
  for (auto* m : {&first, &second, &third})
    (*m)->to(torch::kFloat64);
  reward->to(torch::kFloat64);
  {
    torch::NoGradGuard g;
    first->log_std_param.copy_(torch::tensor({{-1.0, 0.0, 0.5}}));
  }
  const int64_t B = 5;
  const auto s = torch::randn({B, kN}, torch::kFloat64), a = torch::rand({B, kM}, torch::kFloat64) * 2 - 1;
  const double beta = 0.7;
  LearnedRolloutModel model(first, reward, false, EnsembleOptions{{second, third}, beta});
  auto next = torch::empty({B, kN}, torch::kFloat64), r = torch::empty({B}, torch::kFloat64);
  torch::NoGradGuard g;
  model.begin(B, s[0]);
  model.step(s, a, next, r);
  const auto p1 = first->forward(s, a), p2 = second->forward(s, a), p3 = third->forward(s, a);
  const auto r0 = reward->forward(s, a).reshape({B});
  const double sigma2[kN] = {std::exp(-2.0), 1.0, std::exp(1.0)};
  for (int64_t b = 0; b < B; ++b) {
    double u = 0;
    for (int64_t i = 0; i < kN; ++i) {
      const double x1 = p1[b][i].item<double>(), x2 = p2[b][i].item<double>(), x3 = p3[b][i].item<double>();
      const double mean = (x1 + x2 + x3) / 3.0;
      EXPECT_NEAR(next[b][i].item<double>(), mean, 1e-12);
      const double var =
          ((x1 - mean) * (x1 - mean) + (x2 - mean) * (x2 - mean) + (x3 - mean) * (x3 - mean)) / 3.0;
      u += var / sigma2[i] / kN;
    }
    EXPECT_GT(u, 0);
    EXPECT_NEAR(r[b].item<double>(), r0[b].item<double>() - beta * std::sqrt(u), 1e-12) << b;
  }

  // Members that agree: the single model's prediction and no penalty.
  LearnedRolloutModel agreeing(first, reward, false, EnsembleOptions{{copy_of(first), copy_of(first)}, beta});
  agreeing.begin(B, s[0]);
  agreeing.step(s, a, next, r);
  EXPECT_TRUE(torch::allclose(next, p1, 1e-12, 1e-12));
  EXPECT_TRUE(torch::allclose(r, r0, 1e-12, 1e-12));
}

TEST(Ensemble, APenaltyNeedsAnEnsembleAndTheDeterministicPlannersRefuseOne) {
  const DynamicsModelOptions o{kN, kM, 8, Activation::kSin};
  DynamicsModel first(o);
  RewardModel reward(RewardModelOptions{kN, kM, 8});
  EXPECT_NE(testing::error_of([&] {
              LearnedRolloutModel(first, reward, false, EnsembleOptions{{}, 1.0});
            }).find("needs an ensemble"),
            std::string::npos);
  EXPECT_THROW(LearnedRolloutModel(first, reward, false, EnsembleOptions{{DynamicsModel(o)}, -1.0}), Error);

  Config c = make_train_config();
  for (const char* kv : {"model.hidden=8", "model.reward_hidden=8", "policy.hidden=[8]", "model.ensemble=2"})
    c.apply_override(kv);
  LearnedModels models;
  LearnerContext context{c, kN, kM, 1, models};
  make_learner("models", context);
  make_learner("sac", context);
  for (const char* name : {"deterministic_hybrid", "mpc_deterministic"}) {
    const std::string message = testing::error_of([&] { make_controller(name, models, c, true); });
    EXPECT_NE(message.find("model.ensemble must be 1"), std::string::npos) << name << ": " << message;
  }
  EXPECT_NO_THROW(make_controller("stochastic_hybrid", models, c, true));
  EXPECT_NO_THROW(make_controller("mppi", models, c, true));
}

}  // namespace
}  // namespace hlt
