// The learner registry and interface: every registered learner builds from the training config, reports
// the same tags at every update, and continues exactly after its state went through a checkpoint.
#include "agents/learner.h"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>

#include "agents/train_config.h"
#include "hlt/core/checkpoint.h"
#include "hlt/data/replay_buffer.h"
#include "support/error_of.h"
#include "support/random_transitions.h"

namespace hlt {
namespace {

constexpr int64_t kN = 3, kM = 2;

ReplayBuffer filled_buffer(uint64_t seed) {
  return testing::random_transitions(kN, kM, seed);
}

Config small_config() {
  Config c = make_train_config();
  for (const char* kv :
       {"policy.hidden=[8]", "sac.q_hidden=[8,8]", "model.hidden=8", "model.reward_hidden=8"})
    c.apply_override(kv);
  return c;
}

TEST(Learner, RegistryNamesTheLearnersAndRefusesUnknownOnes) {
  const auto names = learner_names();
  for (const char* name : {"sac", "models", "bc"})
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
  const Config c = small_config();
  LearnedModels models;
  LearnerContext context{c, kN, kM, 1, models};
  const std::string message = testing::error_of([&] { make_learner("no_such_learner", context); });
  EXPECT_NE(message.find("known learners: bc, models, sac"), std::string::npos) << message;
}

TEST(Learner, EachLearnerAddsItsNetworksReportsFixedTagsAndResumesExactly) {
  const std::map<std::string, std::vector<std::string>> tags = {
      {"sac", {"loss/critic", "loss/actor", "sac/alpha", "sac/entropy"}},
      {"models", {"loss/dynamics", "loss/reward"}},
      {"bc", {"loss/bc"}}};
  const Config c = small_config();
  const std::string path = (std::filesystem::temp_directory_path() / "hlt_learner_test.pt").string();
  for (const auto& [name, expected_tags] : tags) {
    torch::manual_seed(3);
    LearnedModels models;
    LearnerContext context{c, kN, kM, 11, models};
    auto learner = make_learner(name, context);
    EXPECT_EQ(!models.policy.is_empty(), name != "models") << name;
    EXPECT_EQ(!models.dynamics.is_empty(), name == "models") << name;
    ReplayBuffer buffer = filled_buffer(5);
    for (int i = 0; i < 3; ++i) {
      const NamedLosses losses = learner->train(buffer.sample(16));
      ASSERT_EQ(losses.size(), expected_tags.size()) << name;
      for (size_t k = 0; k < losses.size(); ++k) {
        EXPECT_EQ(losses[k].tag, expected_tags[k]) << name;
        EXPECT_TRUE(std::isfinite(losses[k].value)) << name;
      }
    }
    // Save the learner and its networks; a second learner built from other weights, loaded, continues
    // exactly as the first does.
    CheckpointWriter w;
    if (!models.policy.is_empty()) w.add_module("policy", *models.policy);
    if (!models.dynamics.is_empty()) {
      w.add_module("dynamics", *models.dynamics);
      w.add_module("reward", *models.reward);
    }
    learner->save_training_state(w);
    w.save(path);
    // Two more updates: the second's losses depend on the first's step, so on the optimizer's state too.
    const Batch next = buffer.sample(16), after = buffer.sample(16);
    learner->train(next);
    const NamedLosses first = learner->train(after);

    torch::manual_seed(99);
    LearnedModels other;
    LearnerContext other_context{c, kN, kM, 12, other};
    auto resumed = make_learner(name, other_context);
    CheckpointReader r(path);
    if (!other.policy.is_empty()) r.load_module("policy", *other.policy);
    if (!other.dynamics.is_empty()) {
      r.load_module("dynamics", *other.dynamics);
      r.load_module("reward", *other.reward);
    }
    resumed->load_training_state(r);
    resumed->train(next);
    const NamedLosses second = resumed->train(after);
    ASSERT_EQ(second.size(), first.size());
    for (size_t k = 0; k < first.size(); ++k)
      EXPECT_EQ(second[k].value, first[k].value) << name << " " << first[k].tag;
    if (name == "models") {
      // The dynamics model's domain (the range of the states it was trained on) resumes with it.
      ASSERT_TRUE(models.dynamics->has_domain() && other.dynamics->has_domain());
      EXPECT_TRUE(torch::equal(other.dynamics->domain_low(), models.dynamics->domain_low()));
      EXPECT_TRUE(torch::equal(other.dynamics->domain_high(), models.dynamics->domain_high()));
      EXPECT_TRUE((models.dynamics->domain_low() < models.dynamics->domain_high()).all().item<bool>());
    }
  }
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace hlt
