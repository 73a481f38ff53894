// The demonstrations file format: an exact round trip, and a clear error for every way a file can be wrong.
#include "agents/demonstrations.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "hlt/util/checksum.h"
#include "hlt/util/error.h"
#include "hlt/util/files.h"
#include "support/error_of.h"

namespace hlt {
namespace {

std::string temp(const std::string& name) {
  return (std::filesystem::temp_directory_path() / name).string();
}

Demonstrations sample() {
  Demonstrations d("pendulum", 3, 1, 4, "expert test.txt (ReLU MLP 3x4x1)");
  for (int e = 0; e < 2; ++e) {
    std::vector<DemoStep> steps;
    for (int t = 0; t < 3 + e; ++t) {
      DemoStep s;
      s.observation = Eigen::Vector3d(0.1 * t, -0.2 * e, 1.0 / 3.0);
      s.action = Eigen::VectorXd::Constant(1, 0.5 - 0.1 * t);
      s.next_observation = s.observation * 1.5;
      s.reward = -1.25 * t;
      s.truncated = t == 2 + e;
      steps.push_back(s);
    }
    d.add_episode(steps);
  }
  return d;
}

using testing::error_of;

TEST(Demonstrations, RoundTripIsExact) {
  const std::string path = temp("hlt_demos_rt.hltd");
  const Demonstrations d = sample();
  d.save(path);
  const Demonstrations r = Demonstrations::load(path);
  EXPECT_EQ(r.env(), "pendulum");
  EXPECT_EQ(r.observation_dim(), 3);
  EXPECT_EQ(r.action_dim(), 1);
  EXPECT_EQ(r.frame_skip(), 4);
  EXPECT_EQ(r.source(), d.source());
  ASSERT_EQ(r.episodes().size(), 2u);
  EXPECT_EQ(r.transitions(), 7);
  for (size_t e = 0; e < 2; ++e) {
    ASSERT_EQ(r.episodes()[e].size(), d.episodes()[e].size());
    for (size_t t = 0; t < r.episodes()[e].size(); ++t) {
      const DemoStep &a = d.episodes()[e][t], &b = r.episodes()[e][t];
      EXPECT_EQ(a.observation, b.observation);
      EXPECT_EQ(a.action, b.action);
      EXPECT_EQ(a.next_observation, b.next_observation);
      EXPECT_EQ(a.reward, b.reward);
      EXPECT_EQ(a.terminated, b.terminated);
      EXPECT_EQ(a.truncated, b.truncated);
    }
  }
  r.check_matches("pendulum", 3, 1, 4);
  EXPECT_NE(error_of([&] { r.check_matches("acrobot", 6, 1, 4); }).find("recorded on pendulum"),
            std::string::npos);
  EXPECT_NE(error_of([&] { r.check_matches("pendulum", 3, 1, 1); }).find("frame skip 4"), std::string::npos);
}

TEST(Demonstrations, DamagedAndMalformedFilesAreClearErrors) {
  const std::string path = temp("hlt_demos_bad.hltd");
  sample().save(path);
  const std::string good = read_file(path);
  auto load_error = [&](const std::string& bytes) {
    write_file_atomic(path, bytes);
    return error_of([&] { Demonstrations::load(path); });
  };
  EXPECT_NE(load_error(good.substr(0, good.size() - 100)).find("truncated or corrupt"), std::string::npos);
  std::string flipped = good;
  flipped[good.size() - 200] ^= 4;
  EXPECT_NE(load_error(flipped).find("checksum does not match"), std::string::npos);
  // Well-formed checksums around wrong content.
  const std::string body(verified_content(good, "x"));
  auto replaced = [&](const std::string& from, const std::string& to) {
    std::string b = body;
    b.replace(b.find(from), from.size(), to);
    return with_checksum_trailer(b);
  };
  EXPECT_NE(load_error(replaced("hlt-demonstrations 1", "hlt-demonstrations 7")).find("format version 7"),
            std::string::npos);
  EXPECT_NE(load_error(replaced("transitions 7", "transitions 9")).find("promises 9 transitions"),
            std::string::npos);
  EXPECT_NE(load_error(replaced("episodes 2", "episodes 3")).find("promises 3 episodes"), std::string::npos);
  EXPECT_NE(load_error(replaced("action_dim 1", "action_dim x")).find("'action_dim' must be a non-negative"),
            std::string::npos);
  EXPECT_NE(load_error(with_checksum_trailer("not demonstrations\n")).find("expected a 'hlt-demonstrations'"),
            std::string::npos);
  EXPECT_NE(error_of([] { Demonstrations::load("/nonexistent.hltd"); }).find("/nonexistent.hltd"),
            std::string::npos);
  // Non-finite numbers are refused when recorded.
  Demonstrations d("pendulum", 3, 1, 4, "x");
  DemoStep s{Eigen::Vector3d(0, std::nan(""), 0), Eigen::VectorXd::Zero(1), Eigen::Vector3d::Zero(), 0};
  EXPECT_NE(error_of([&] { d.add_episode({s}); }).find("non-finite"), std::string::npos);
}

}  // namespace
}  // namespace hlt
