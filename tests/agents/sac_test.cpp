#include "agents/sac.h"

#include <gtest/gtest.h>
#include <torch/torch.h>
#include <map>

#include <ATen/CPUGeneratorImpl.h>

#include "agents/model_learner.h"
#include "hlt/core/checkpoint.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

// A one-step bandit: every transition is terminal with reward -(a - 0.5)^2 (summed over dims), so the
// optimal soft policy concentrates near a = 0.5 and Q(s, a) approaches the reward.
ReplayBuffer bandit_buffer(int n, int m, int size, uint64_t seed) {
  ReplayBuffer rb(size, n, m, seed);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < size; ++i) {
    std::vector<double> s(n), a(m), s2(n);
    double r = 0;
    for (auto& x : s)
      x = u(rng);
    for (auto& x : a) {
      x = u(rng);
      r -= (x - 0.5) * (x - 0.5);
    }
    rb.add(s.data(), a.data(), r, s2.data(), a.data(), true);
  }
  return rb;
}

TEST(Sac, LearnsTheOneStepBandit) {
  torch::manual_seed(0);
  const int n = 2, m = 1;
  GaussianPolicy policy(GaussianPolicyOptions{n, m, {64}, Activation::kRelu});
  SacOptions o;
  o.q_hidden = {64, 64};
  o.q_lr = o.policy_lr = o.alpha_lr = 3e-3;
  Sac sac(policy, n, m, o);
  ReplayBuffer rb = bandit_buffer(n, m, 2000, 1);
  SacLosses first = sac.update(rb.sample(128)), last;
  for (int i = 0; i < 600; ++i)
    last = sac.update(rb.sample(128));
  EXPECT_LT(last.critic, first.critic);
  const auto mean = policy->mean_action(torch::rand({64, n}) * 2 - 1);
  EXPECT_NEAR(mean.mean().item<double>(), 0.5, 0.1);
  // Automatic entropy tuning: with the target -m, alpha moves down from 1 as the policy sharpens.
  EXPECT_LT(last.alpha, 1.0);
  EXPECT_TRUE(std::isfinite(last.actor) && std::isfinite(last.entropy));
}

double relative_difference(const torch::Tensor& a, const torch::Tensor& b) {
  return (a - b).norm().item<double>() / std::max(b.norm().item<double>(), 1e-12);
}

// The update's hand-written gradients against autograd on the losses they differentiate: the critics'
// from the same initial networks and noise, the policy's after the same critic step. With `normalized` the
// policy normalises its inputs (the hand-written actor pass then runs on the normalised states). With
// `bc_weight` the actor's loss also has the behaviour-cloning term on the batch's actions, two of which are
// at the bounds (their targets clipped to +-kBcActionClip).
void expect_hand_written_gradients_match_autograd(bool normalized, double bc_weight = 0.0) {
  const int n = 3, m = 2, B = 32;
  SacOptions o;
  o.q_hidden = {20, 14};
  o.seed = 5;
  o.initial_alpha = 0.7;
  o.bc_weight = bc_weight;
  auto make = [&] {
    torch::manual_seed(11);
    GaussianPolicyOptions po{n, m, {16, 12}, Activation::kSin};
    if (normalized) {
      po.input_offset = {0.3, -1.0, 2.0};
      po.input_scale = {0.1, 2.0, 0.5};
    }
    GaussianPolicy p(po);
    return std::make_unique<Sac>(p, n, m, o);
  };
  auto sac = make(), ref = make();
  torch::manual_seed(12);
  Batch b;
  b.states = torch::randn({B, n});
  b.actions = torch::rand({B, m}) * 1.8 - 0.9;
  if (bc_weight > 0) {
    b.actions[0][0] = 1.0;
    b.actions[1][1] = -1.0;
  }
  b.rewards = torch::randn({B, 1});
  b.next_states = torch::randn({B, n});
  b.next_actions = torch::rand({B, m}) * 1.8 - 0.9;
  b.dones = (torch::rand({B, 1}) < 0.3).to(torch::kFloat32);
  const SacLosses losses = sac->update(b);

  at::Generator gen = at::make_generator<at::CPUGeneratorImpl>(o.seed);
  const torch::Tensor alpha = torch::full({1}, std::log(o.initial_alpha)).exp();
  torch::Tensor target;
  {
    torch::NoGradGuard ng;  // the target critics start as copies of the critics
    PolicySample next = ref->policy()->rsample(b.next_states, gen);
    target = b.rewards + o.gamma * (1.0 - b.dones) *
                             (ref->critics()->min_q(b.next_states, next.action) - alpha * next.log_prob);
  }
  const torch::Tensor critic_loss =
      (ref->critics()->forward(b.states, b.actions) - target).square().mean() * 2.0;
  const auto critic_params = ref->critics()->parameters();
  const auto critic_grads = torch::autograd::grad({critic_loss}, critic_params);
  const auto written = sac->critics()->parameters();
  for (size_t i = 0; i < critic_params.size(); ++i)
    EXPECT_LT(relative_difference(written[i].grad(), critic_grads[i]), 1e-5) << "critic parameter " << i;
  EXPECT_NEAR(losses.critic, 0.5 * critic_loss.item<double>(), 1e-6 * std::abs(losses.critic));

  {
    torch::NoGradGuard ng;
    for (size_t i = 0; i < critic_params.size(); ++i)
      critic_params[i].copy_(written[i]);
  }
  PolicySample fresh = ref->policy()->rsample(b.states, gen);
  torch::Tensor actor_loss = (alpha * fresh.log_prob - ref->critics()->min_q(b.states, fresh.action)).mean();
  torch::Tensor bc_loss;
  if (bc_weight > 0) {
    auto [mean, log_std] = ref->policy()->forward(b.states);
    const torch::Tensor target = b.actions.clamp(-kBcActionClip, kBcActionClip);
    bc_loss = -GaussianPolicyImpl::squashed_log_prob(torch::atanh(target), target, mean, log_std).mean();
    actor_loss = actor_loss + bc_weight * bc_loss;
  }
  const auto policy_params = ref->policy()->parameters();
  const auto policy_grads = torch::autograd::grad({actor_loss}, policy_params, {}, false, false, true);
  const auto written_policy = sac->policy()->parameters();
  for (size_t i = 0; i < policy_params.size(); ++i) {
    ASSERT_TRUE(policy_grads[i].defined());
    EXPECT_LT(relative_difference(written_policy[i].grad(), policy_grads[i]), 1e-4)
        << ref->policy()->named_parameters().keys()[i];
  }
  const double reported = losses.actor + (bc_weight > 0 ? bc_weight * losses.bc : 0.0);
  EXPECT_NEAR(reported, actor_loss.item<double>(), 1e-5 * std::abs(reported) + 1e-6);
  if (bc_weight > 0) {
    EXPECT_NEAR(losses.bc, bc_loss.item<double>(), 1e-5 * std::abs(losses.bc) + 1e-6);
  }
  EXPECT_NEAR(losses.entropy, -fresh.log_prob.mean().item<double>(), 1e-5 * std::abs(losses.entropy) + 1e-6);
}

TEST(Sac, HandWrittenGradientsMatchAutograd) {
  expect_hand_written_gradients_match_autograd(false);
}

TEST(Sac, HandWrittenGradientsMatchAutogradWithNormalisedPolicyInputs) {
  expect_hand_written_gradients_match_autograd(true);
}

TEST(Sac, BehaviourCloningTermOnTheStoredActionsMatchesAutograd) {
  expect_hand_written_gradients_match_autograd(false, 0.5);
  expect_hand_written_gradients_match_autograd(true, 2.0);
}

// The term pulls the policy's mean towards the stored actions: with it the mean moves towards a constant
// stored action that the critic does not favour; without it, not.
TEST(Sac, BehaviourCloningTermMovesThePolicyTowardsTheStoredActions) {
  const int n = 2, m = 1, B = 64;
  auto final_mean = [&](double bc_weight) {
    torch::manual_seed(3);
    GaussianPolicy policy(GaussianPolicyOptions{n, m, {32}, Activation::kRelu});
    SacOptions o;
    o.q_hidden = {32, 32};
    o.q_lr = o.policy_lr = o.alpha_lr = 3e-3;
    o.bc_weight = bc_weight;
    Sac sac(policy, n, m, o);
    ReplayBuffer rb(B * 4, n, m, 1);
    torch::manual_seed(4);
    const torch::Tensor s = torch::rand({B * 4, n}) * 2 - 1;
    for (int i = 0; i < B * 4; ++i) {
      // Every stored action is -0.6 with reward 0: the critic learns no preference, the term has one.
      const std::vector<double> si = {s[i][0].item<double>(), s[i][1].item<double>()}, a = {-0.6};
      rb.add(si.data(), a.data(), 0.0, si.data(), a.data(), true);
    }
    for (int i = 0; i < 300; ++i)
      sac.update(rb.sample(B));
    return policy->mean_action(s).mean().item<double>();
  };
  EXPECT_NEAR(final_mean(1.0), -0.6, 0.1);
  EXPECT_GT(std::abs(final_mean(0.0) + 0.6), 0.3);
}

TEST(Sac, CheckpointRoundTripContinuesIdentically) {
  torch::manual_seed(3);
  const int n = 3, m = 2;
  auto make = [&] {
    GaussianPolicy p(GaussianPolicyOptions{n, m, {32}, Activation::kSin});
    SacOptions o;
    o.q_hidden = {32, 32};
    return std::make_unique<Sac>(p, n, m, o);
  };
  auto a = make();
  ReplayBuffer rb = bandit_buffer(n, m, 500, 2);
  for (int i = 0; i < 5; ++i)
    a->update(rb.sample(64));
  const std::string path = "/tmp/hlt_sac_ckpt_test.pt";
  {
    CheckpointWriter w;
    a->save(w);
    w.save(path);
  }
  auto b = make();
  {
    CheckpointReader r(path);
    b->load(r);
  }
  const Batch batch = rb.sample(64);
  torch::manual_seed(9);
  const SacLosses la = a->update(batch);
  torch::manual_seed(9);
  const SacLosses lb = b->update(batch);
  EXPECT_DOUBLE_EQ(la.critic, lb.critic);
  EXPECT_DOUBLE_EQ(la.actor, lb.actor);
  EXPECT_DOUBLE_EQ(la.alpha, lb.alpha);
}

TEST(ModelLearner, FitsLinearDynamicsAndReward) {
  torch::manual_seed(0);
  const int n = 2, m = 1;
  DynamicsModel dyn(DynamicsModelOptions{n, m, 64, Activation::kSin});
  RewardModel rew(RewardModelOptions{n, m, 64});
  ModelLearner learner(dyn, rew, ModelLearnerOptions{3e-3, 0.0, 0.5});
  // s' = s + 0.1 [a, -s0], r = -s0^2.
  ReplayBuffer rb(4000, n, m, 0);
  std::mt19937_64 rng(0);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 4000; ++i) {
    double s[2] = {u(rng), u(rng)}, a[1] = {u(rng)};
    double s2[2] = {s[0] + 0.1 * a[0], s[1] - 0.1 * s[0]};
    rb.add(s, a, -s[0] * s[0], s2, a, false);
  }
  ModelLosses first = learner.update(rb.sample(128)), last;
  for (int i = 0; i < 1500; ++i)
    last = learner.update(rb.sample(128));
  EXPECT_LT(last.reward, 0.02 * first.reward);
  EXPECT_LT(last.dynamics, first.dynamics - 2.0);  // the NLL falls as the learned std shrinks
  torch::NoGradGuard g;
  auto s = torch::tensor({{0.3f, -0.2f}}), a = torch::tensor({{0.5f}});
  auto pred = dyn->forward(s, a);
  EXPECT_NEAR(pred[0][0].item<float>(), 0.35, 0.02);
  EXPECT_NEAR(pred[0][1].item<float>(), -0.23, 0.02);
  EXPECT_NEAR(rew->forward(s, a).item<float>(), -0.09, 0.03);
}

// A reward model of the next state (model.reward_input next_state) regresses r on (s', a): the first
// update's reward loss is the hand-computed mean((r - r(s', a))^2) before it, not mean((r - r(s, a))^2); and
// such a model cannot take a TD target (gamma > 0 is refused).
TEST(ModelLearner, ARewardModelOfTheNextStateRegressesOnTheReachedState) {
  torch::manual_seed(5);
  const int n = 2, m = 1;
  DynamicsModel dyn(DynamicsModelOptions{n, m, 16, Activation::kSin});
  RewardModelOptions ro{n, m, 16};
  ro.reads_next_state = true;
  RewardModel rew(ro);
  EXPECT_THROW(ModelLearner(dyn, rew, ModelLearnerOptions{3e-3, 0.5, 0.5}), Error);
  ModelLearner learner(dyn, rew, ModelLearnerOptions{3e-3, 0.0, 0.5});
  ReplayBuffer rb(256, n, m, 0);
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 256; ++i) {
    double s[2] = {u(rng), u(rng)}, a[1] = {u(rng)};
    double s2[2] = {s[0] + 0.5 * a[0], s[1] - 0.5 * s[0]};
    rb.add(s, a, -s2[0] * s2[0], s2, a, false);
  }
  const Batch batch = rb.all();
  double on_next = 0, on_state = 0;
  {
    torch::NoGradGuard g;
    on_next = (batch.rewards - rew->forward(batch.next_states, batch.actions)).square().mean().item<double>();
    on_state = (batch.rewards - rew->forward(batch.states, batch.actions)).square().mean().item<double>();
  }
  const ModelLosses first = learner.update(batch);
  EXPECT_NEAR(first.reward, on_next, 1e-6 * on_next);
  EXPECT_GT(std::abs(on_state - on_next), 1e-3 * on_next);
  // And it fits r = -s'_0^2 as a function of s'.
  ModelLosses last;
  for (int i = 0; i < 1500; ++i)
    last = learner.update(rb.sample(128));
  EXPECT_LT(last.reward, 0.02 * first.reward);
  torch::NoGradGuard g;
  EXPECT_NEAR(rew->forward(torch::tensor({{0.6f, 0.1f}}), torch::tensor({{0.2f}})).item<float>(), -0.36,
              0.05);
}

// A model learner with `options` on fresh 16-wide models of n states and m actions, their initial weights
// drawn after torch::manual_seed(seed): learners made with the same seed start from identical networks.
std::unique_ptr<ModelLearner> seeded_model_learner(uint64_t seed, int n, int m, Activation activation,
                                                   const ModelLearnerOptions& options, DynamicsModel* dyn,
                                                   RewardModel* rew) {
  torch::manual_seed(seed);
  *dyn = DynamicsModel(DynamicsModelOptions{n, m, 16, activation});
  *rew = RewardModel(RewardModelOptions{n, m, 16});
  return std::make_unique<ModelLearner>(*dyn, *rew, options);
}

// The decay adds weight_decay * W to the likelihood's gradient of each weight matrix, and nothing to the
// biases, the log-std or the reward model: two learners from identical networks, one batch, compared.
TEST(ModelLearner, WeightDecayAddsTheL2GradientToTheDynamicsWeightsOnly) {
  const int n = 3, m = 2;
  const double wd = 0.01;
  ModelLearnerOptions decaying;
  decaying.weight_decay = wd;
  DynamicsModel dyn_a(nullptr), dyn_b(nullptr);
  RewardModel rew_a(nullptr), rew_b(nullptr);
  auto plain = seeded_model_learner(7, n, m, Activation::kRelu, {}, &dyn_a, &rew_a);
  auto decayed = seeded_model_learner(7, n, m, Activation::kRelu, decaying, &dyn_b, &rew_b);
  ReplayBuffer rb(64, n, m, 0);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 64; ++i) {
    double s[3] = {u(rng), u(rng), u(rng)}, a[2] = {u(rng), u(rng)};
    double s2[3] = {s[0] + 0.1 * a[0], s[1] * s[2], s[2] - 0.1 * a[1]};
    rb.add(s, a, s[0], s2, a, false);
  }
  std::map<std::string, torch::Tensor> before;
  for (const auto& p : dyn_b->named_parameters())
    before[p.key()] = p.value().detach().clone();
  const Batch batch = rb.all();
  plain->update(batch);
  decayed->update(batch);
  const auto pa = dyn_a->named_parameters(), pb = dyn_b->named_parameters();
  int weights = 0;
  for (const auto& p : pb) {
    const torch::Tensor diff = p.value().grad() - pa[p.key()].grad();
    const bool is_weight = p.key().size() >= 6 && p.key().substr(p.key().size() - 6) == "weight";
    const torch::Tensor expected = is_weight ? wd * before[p.key()] : torch::zeros_like(diff);
    EXPECT_TRUE(torch::allclose(diff, expected, 1e-6, 1e-7)) << p.key();
    weights += is_weight;
  }
  EXPECT_EQ(weights, 2);  // fc1 and fc2
  const auto ra = rew_a->named_parameters(), rb2 = rew_b->named_parameters();
  for (const auto& p : rb2)
    EXPECT_TRUE(torch::equal(p.value().grad(), ra[p.key()].grad())) << p.key();
}

// With model.hard_mining c the learner takes c times the batch: the dynamics model steps exactly as a plain
// learner given the rows it predicted worst before the step (chosen here by hand), the reward model exactly
// as one given the first (uniform) rows, and the logged dynamics loss is the uniform rows' NLL before the
// step. It refuses sequences.
TEST(ModelLearner, HardMiningFitsTheDynamicsToTheWorstPredictedRows) {
  const int n = 2, m = 1, B = 16, c = 3;
  ModelLearnerOptions mining;
  mining.hard_mining = c;
  DynamicsModel dyn_a(nullptr), dyn_b(nullptr), dyn_c(nullptr);
  RewardModel rew_a(nullptr), rew_b(nullptr), rew_c(nullptr);
  auto mined = seeded_model_learner(9, n, m, Activation::kSin, mining, &dyn_a, &rew_a);
  auto on_hard = seeded_model_learner(9, n, m, Activation::kSin, {}, &dyn_b, &rew_b);
  auto on_uniform = seeded_model_learner(9, n, m, Activation::kSin, {}, &dyn_c, &rew_c);
  EXPECT_EQ(mined->batch_multiple(), c);
  EXPECT_EQ(on_hard->batch_multiple(), 1);
  ReplayBuffer rb(B * c, n, m, 0);
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < B * c; ++i) {
    // A kink at s0 = 0.5 that a fresh model predicts badly on one side only.
    double s[2] = {u(rng), u(rng)}, a[1] = {u(rng)};
    double s2[2] = {s[0] > 0.5 ? -s[0] : s[0] + 0.1 * a[0], s[1]};
    rb.add(s, a, s[1], s2, a, false);
  }
  const Batch all = rb.all();
  torch::Tensor hard;
  double uniform_nll = 0;
  {
    torch::NoGradGuard g;
    const torch::Tensor z =
        (all.next_states - dyn_a->forward(all.states, all.actions)) / dyn_a->log_std().exp();
    const torch::Tensor err = z.square().sum(1);
    hard = std::get<0>(std::get<1>(err.sort(0, /*descending=*/true)).narrow(0, 0, B).sort());
    uniform_nll = 0.5 * z.narrow(0, 0, B).square().mean().item<double>() +
                  dyn_a->log_std().mean().item<double>() + 0.5 * std::log(2.0 * M_PI);
    // The chosen rows are not the uniform ones: the test can tell them apart.
    ASSERT_FALSE(torch::equal(hard, torch::arange(B, torch::kLong)));
  }
  const ModelLosses l = mined->update(all);
  on_hard->update(select_rows(all, hard));
  on_uniform->update(select_rows(all, torch::arange(B, torch::kLong)));
  EXPECT_NEAR(l.dynamics, uniform_nll, 1e-5 * std::abs(uniform_nll));
  const auto pa = dyn_a->named_parameters(), pb = dyn_b->named_parameters();
  for (const auto& p : pa)
    EXPECT_TRUE(torch::allclose(p.value(), pb[p.key()], 1e-6, 1e-7)) << "dynamics " << p.key();
  const auto ra = rew_a->named_parameters(), rc = rew_c->named_parameters();
  for (const auto& p : ra)
    EXPECT_TRUE(torch::allclose(p.value(), rc[p.key()], 1e-6, 1e-7)) << "reward " << p.key();
  ModelLearnerOptions o;
  o.hard_mining = 2;
  o.rollout_steps = 3;
  DynamicsModel d(nullptr);
  RewardModel r(nullptr);
  EXPECT_THROW(seeded_model_learner(9, n, m, Activation::kSin, o, &d, &r), Error);
}

// With model.rollout_steps K the learner takes sequences: the dynamics model gets the open-loop loss's
// gradient, the reward model exactly the gradient it gets from the sequences' first transitions alone (so
// its parameters after one Adam step are those of a one-step learner given those transitions), and a batch
// of the wrong length is refused.
TEST(ModelLearner, SequencesTrainTheDynamicsOpenLoopAndTheRewardOnTheirFirstSteps) {
  const int n = 2, m = 1, K = 3;
  ModelLearnerOptions sequences;
  sequences.rollout_steps = K;
  DynamicsModel dyn_1(nullptr), dyn_k(nullptr), dyn_ref(nullptr);
  RewardModel rew_1(nullptr), rew_k(nullptr), rew_ref(nullptr);
  auto one = seeded_model_learner(8, n, m, Activation::kSin, {}, &dyn_1, &rew_1);
  auto seq = seeded_model_learner(8, n, m, Activation::kSin, sequences, &dyn_k, &rew_k);
  // Untrained copies, for the expected loss.
  seeded_model_learner(8, n, m, Activation::kSin, sequences, &dyn_ref, &rew_ref);
  EXPECT_EQ(one->sequence_steps(), 1);
  EXPECT_EQ(seq->sequence_steps(), K);
  // Two episodes of s' = 0.9 s + 0.1 a.
  ReplayBuffer rb(40, n, m, 2);
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int e = 0; e < 2; ++e) {
    double s[2] = {u(rng), u(rng)};
    for (int t = 0; t < 20; ++t) {
      const double a[1] = {u(rng)}, s2[2] = {0.9 * s[0] + 0.1 * a[0], 0.9 * s[1]};
      rb.add(s, a, s[0], s2, a, false);
      s[0] = s2[0];
      s[1] = s2[1];
    }
  }
  const Batch batch = rb.sample(16, K);
  auto first = [&](const torch::Tensor& t) { return t.narrow(0, 0, 16).contiguous(); };
  const Batch firsts{first(batch.states),
                     first(batch.actions),
                     first(batch.rewards),
                     first(batch.next_states),
                     first(batch.next_actions),
                     first(batch.dones),
                     1};
  EXPECT_THROW(seq->update(firsts), Error);
  EXPECT_THROW(one->update(batch), Error);
  const double expected =
      dyn_ref->rollout_loss(firsts.states, batch.actions, batch.next_states).item<double>();
  const ModelLosses ls = seq->update(batch), l1 = one->update(firsts);
  EXPECT_NEAR(ls.dynamics, expected, 1e-6 * std::abs(expected));
  EXPECT_DOUBLE_EQ(ls.reward, l1.reward);
  const auto r1 = rew_1->named_parameters();
  for (const auto& p : rew_k->named_parameters())
    EXPECT_TRUE(torch::equal(p.value(), r1[p.key()])) << p.key();
  EXPECT_FALSE(torch::equal(dyn_k->fc1->weight, dyn_1->fc1->weight));
}

}  // namespace
}  // namespace hlt
