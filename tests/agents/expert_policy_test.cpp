// The expert policy loader against a hand computation, its error messages, and the shipped Ant expert's
// return on `ant` (the figure agents/experts/README.md and the data's source report).
#include "agents/expert_policy.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

#include "envs/registry.h"
#include "hlt/util/error.h"
#include "hlt/util/files.h"

namespace hlt {
namespace {
namespace fs = std::filesystem;

std::string write_temp(const std::string& name, const std::string& text) {
  const std::string path = (fs::temp_directory_path() / name).string();
  write_file_atomic(path, text);
  return path;
}

std::string error_of(const std::string& text) {
  try {
    ExpertPolicy p(write_temp("hlt_expert_bad.txt", text));
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

const char* kTiny =
    "l1_w 2 3\n1 0 -1\n0 2 1\n"
    "l1_b 1 3\n0 0 0.5\n"
    "out_w 3 1\n1\n1\n1\n"
    "out_b 1 1\n-0.25\n";

TEST(ExpertPolicy, MatchesAHandComputation) {
  ExpertPolicy p(write_temp("hlt_expert_tiny.txt", kTiny));
  EXPECT_EQ(p.observation_dim(), 2);
  EXPECT_EQ(p.action_dim(), 1);
  // x = (0.2, 0.1): h = relu(0.2, 0.2, -0.2 + 0.1 + 0.5 = 0.4) = (0.2, 0.2, 0.4); a = 0.8 - 0.25 = 0.55.
  EXPECT_NEAR(p.act(Eigen::Vector2d(0.2, 0.1))(0), 0.55, 1e-12);
  // x = (-1, 0): h = relu(-1, 0, 1.5) = (0, 0, 1.5); a = 1.25, clipped to 1.
  EXPECT_EQ(p.act(Eigen::Vector2d(-1, 0))(0), 1.0);
  EXPECT_THROW(p.act(Eigen::Vector3d(0, 0, 0)), Error);
}

TEST(ExpertPolicy, MalformedFilesAreClearErrors) {
  EXPECT_NE(error_of("l1_w 2 3\n1 0 -1\n").find("truncated: 1 of its 2 rows are missing"), std::string::npos);
  EXPECT_NE(error_of("l1_w two 3\n").find("expected a header 'NAME ROWS COLS'"), std::string::npos);
  EXPECT_NE(error_of("l1_w 1 2\n1 nan\nl1_b 1 2\n0 0\n").find("'nan' is not a finite number"),
            std::string::npos);
  EXPECT_NE(error_of("l1_w 1 2\n1 2 3\nl1_b 1 2\n0 0\n").find("more than 2 numbers"), std::string::npos);
  EXPECT_NE(error_of("l1_w 1 2\n1 2\nl1_b 1 3\n0 0 0\n").find("expected 1x2"), std::string::npos);
  EXPECT_NE(error_of("l1_w 1 2\n1 2\nl1_b 1 2\n0 0\nl2_w 3 1\n1\n1\n1\nl2_b 1 1\n0\n").find("has 3 rows"),
            std::string::npos);
  EXPECT_NE(error_of("l1_w 1 2\n1 2\n").find("pairs of arrays"), std::string::npos);
  EXPECT_NE(error_of("").find("pairs of arrays"), std::string::npos);
  try {
    ExpertPolicy p("/nonexistent/expert.txt");
    ADD_FAILURE();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/expert.txt"), std::string::npos);
  }
}

TEST(ExpertPolicy, ShippedAntExpertScoresItsPublishedReturn) {
  const char* source = std::getenv("HLT_SOURCE_DIR");
  ASSERT_NE(source, nullptr) << "run through ctest (HLT_SOURCE_DIR)";
  ExpertPolicy expert(std::string(source) + "/agents/experts/ant_pybullet_2017may.txt");
  EXPECT_EQ(expert.observation_dim(), 28);
  EXPECT_EQ(expert.action_dim(), 8);
  auto env = make_env("ant");
  const EpisodeStats s = run_episode(*env, expert, 0);
  EXPECT_EQ(s.length, 1000);
  // 2342.2 on reset seed 0 at frame skip 1 (README of the data: 2342); a random policy scores about 350.
  EXPECT_NEAR(s.episode_return, 2342.2, 1.0);
}

}  // namespace
}  // namespace hlt
