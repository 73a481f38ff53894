#include "hlt/data/replay_buffer.h"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <filesystem>
#include <map>
#include <set>
#include <string>

#include "hlt/core/checkpoint.h"
#include "hlt/util/error.h"

namespace hlt {
namespace {

void add_numbered(ReplayBuffer& rb, int i) {
  const double s[2] = {double(i), -double(i)}, a[1] = {i * 0.5}, s2[2] = {i + 1.0, 0}, a2[1] = {i * 0.25};
  rb.add(s, a, 10.0 * i, s2, a2, i % 3 == 0);
}

TEST(ReplayBuffer, StoresFieldsAndWrapsAround) {
  ReplayBuffer rb(5, 2, 1, 0);
  for (int i = 0; i < 3; ++i)
    add_numbered(rb, i);
  EXPECT_EQ(rb.size(), 3);
  Batch b = rb.all();
  EXPECT_EQ(b.states[2][0].item<float>(), 2.0f);
  EXPECT_EQ(b.states[2][1].item<float>(), -2.0f);
  EXPECT_EQ(b.actions[1][0].item<float>(), 0.5f);
  EXPECT_EQ(b.rewards[2][0].item<float>(), 20.0f);
  EXPECT_EQ(b.next_states[1][0].item<float>(), 2.0f);
  EXPECT_EQ(b.next_actions[2][0].item<float>(), 0.5f);
  EXPECT_EQ(b.dones[0][0].item<float>(), 1.0f);
  EXPECT_EQ(b.dones[1][0].item<float>(), 0.0f);
  for (int i = 3; i < 12; ++i)
    add_numbered(rb, i);
  EXPECT_EQ(rb.size(), 5);
  b = rb.all();  // oldest first: 7, 8, 9, 10, 11
  for (int j = 0; j < 5; ++j)
    EXPECT_EQ(b.states[j][0].item<float>(), 7.0f + j);
}

TEST(ReplayBuffer, SamplingIsUniformAndSeeded) {
  const int cap = 10;
  ReplayBuffer rb(cap, 2, 1, 42), rb2(cap, 2, 1, 42);
  for (int i = 0; i < 25; ++i) {  // wrapped: holds 15..24
    add_numbered(rb, i);
    add_numbered(rb2, i);
  }
  const int draws = 100000;
  std::vector<int> counts(cap, 0);
  Batch b = rb.sample(draws);
  EXPECT_EQ(b.states.sizes(), (std::vector<int64_t>{draws, 2}));
  auto acc = b.states.accessor<float, 2>();
  for (int i = 0; i < draws; ++i) {
    const int v = static_cast<int>(acc[i][0]);
    ASSERT_GE(v, 15);
    ASSERT_LE(v, 24);
    counts[v - 15]++;
  }
  // Chi-square with 9 degrees of freedom: the 99.9% quantile is 27.9.
  double chi2 = 0;
  const double expected = double(draws) / cap;
  for (int c : counts)
    chi2 += (c - expected) * (c - expected) / expected;
  EXPECT_LT(chi2, 27.9);
  // Rows stay together: reward and action belong to the same transition as the state.
  EXPECT_TRUE(torch::allclose(b.rewards.squeeze(1), b.states.select(1, 0) * 10));
  EXPECT_TRUE(torch::equal(rb2.sample(draws).states, b.states));  // same seed, same draws
  EXPECT_THROW(ReplayBuffer(4, 2, 1, 0).sample(3), Error);
}

TEST(ReplayBuffer, SaveLoadRoundTripContinuesIdentically) {
  const std::string path = (std::filesystem::temp_directory_path() / "hlt_rb_test.pt").string();
  ReplayBuffer rb(8, 2, 1, 7);
  for (int i = 0; i < 11; ++i)
    add_numbered(rb, i);
  rb.sample(3);
  {
    CheckpointWriter w;
    rb.save(w.archive("buffer"));
    w.save(path);
  }
  ReplayBuffer restored(8, 2, 1, 999);
  {
    CheckpointReader r(path);
    restored.load(r.archive("buffer"));
  }
  EXPECT_EQ(restored.size(), rb.size());
  EXPECT_TRUE(torch::equal(restored.all().states, rb.all().states));
  EXPECT_TRUE(torch::equal(restored.sample(16).next_actions, rb.sample(16).next_actions));
  add_numbered(rb, 11);
  add_numbered(restored, 11);
  EXPECT_TRUE(torch::equal(restored.all().rewards, rb.all().rewards));
  ReplayBuffer wrong(8, 3, 1, 0);
  CheckpointReader r(path);
  EXPECT_THROW(wrong.load(r.archive("buffer")), Error);
}

TEST(ReplayBuffer, CapacityBeyondMemoryIsRefusedUpFront) {
  try {
    ReplayBuffer rb(100'000'000'000, 28, 8, 0);  // 30 TB
    ADD_FAILURE() << "allocated";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("lower train.replay_capacity"), std::string::npos) << e.what();
  }
}

// Episodes of lengths 5, 2 (ended by a terminal state that, contrived, equals the next episode's start) and
// 6 in a ring of 12 that has wrapped: sequences of 3 start only where 3 transitions of one episode follow,
// may run across the ring's end, come time-major, and all such starts are drawn.
TEST(ReplayBuffer, SequencesStayInsideOneEpisode) {
  ReplayBuffer rb(12, 2, 1, 9);
  auto episode = [&](double start, int length, bool terminal) {
    for (int t = 0; t < length; ++t) {
      const double s[2] = {start + t, 1}, a[1] = {start + t}, s2[2] = {start + t + 1, 1}, a2[1] = {0};
      rb.add(s, a, t, s2, a2, terminal && t == length - 1);
    }
  };
  episode(0, 3, false);    // overwritten by the last episode's tail
  episode(100, 5, false);  // insertion positions 0-4 once the ring holds 12
  episode(200, 2, true);   // 5-6; its last next state (202) is not the next state (300), but:
  episode(202, 1, false);  // 7: continues 200-201's states, yet follows a terminal transition
  episode(300, 4, false);  // 8-11, rows 1-4 of the ring after wrapping
  ASSERT_EQ(rb.size(), 12);
  // Valid starts of 3: 100, 101, 102 and 300, 301.
  const std::set<float> valid{100, 101, 102, 300, 301};
  std::map<float, int> seen;
  const int B = 4000;
  const Batch b = rb.sample(B, 3);
  ASSERT_EQ(b.steps, 3);
  ASSERT_EQ(b.states.size(0), 3 * B);
  auto s = b.states.accessor<float, 2>(), s2 = b.next_states.accessor<float, 2>();
  auto act = b.actions.accessor<float, 2>();
  for (int i = 0; i < B; ++i) {
    ASSERT_TRUE(valid.count(s[i][0])) << s[i][0];
    ++seen[s[i][0]];
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(s[k * B + i][0], s[i][0] + k);
      EXPECT_EQ(act[k * B + i][0], s[i][0] + k);  // rows of one transition stay together
      if (k < 2) {
        EXPECT_EQ(s2[k * B + i][0], s[(k + 1) * B + i][0]);
      }
    }
  }
  ASSERT_EQ(seen.size(), valid.size());
  for (const auto& [start, count] : seen)
    EXPECT_NEAR(count, B / 5.0, 0.1 * B / 5.0) << start;
  // One step is the plain sampler; more steps than any episode holds is an error naming the setting.
  EXPECT_EQ(rb.sample(8, 1).steps, 1);
  try {
    rb.sample(2, 6);
    FAIL() << "sequences of 6 do not exist";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("model.rollout_steps"), std::string::npos) << e.what();
  }
  EXPECT_THROW(rb.sample(2, 13), Error);
  EXPECT_THROW(rb.sample(2, 0), Error);
}

}  // namespace
}  // namespace hlt
