#include "hlt/util/config.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "hlt/util/checksum.h"
#include "hlt/util/error.h"
#include "hlt/util/files.h"
#include "support/error_of.h"

namespace hlt {
namespace {

Config make_config() {
  Config c;
  c.add_string("env", "pendulum", "environment name", {"pendulum", "cartpole_swingup"})
      .add_int("seed", 0, "run seed", 0, 1000000)
      .add_double("planner.lambda", 0.1, "temperature", 1e-6, 1e6)
      .add_int("planner.samples", 20, "samples", 1, 10000)
      .add_bool("planner.clamp_adjoint", false, "clamp rho")
      .add_int_list("policy.hidden", {128}, "hidden sizes", 1, 4096);
  return c;
}

std::string message_of(const std::function<void()>& f) {
  return testing::error_of(f);
}

TEST(Config, DefaultsAndYamlAndOverrides) {
  Config c = make_config();
  EXPECT_EQ(c.get_string("env"), "pendulum");
  c.merge_yaml("env: cartpole_swingup\nplanner:\n  samples: 60\n  lambda: 2\npolicy:\n  hidden: [128, 64]\n",
               "test");
  EXPECT_EQ(c.get_string("env"), "cartpole_swingup");
  EXPECT_EQ(c.get_int("planner.samples"), 60);
  EXPECT_DOUBLE_EQ(c.get_double("planner.lambda"), 2.0);  // an integer literal is a valid float
  EXPECT_EQ(c.get_int_list("policy.hidden"), (Config::IntList{128, 64}));
  c.apply_override("planner.samples=7");
  c.apply_override("planner.clamp_adjoint=true");
  c.apply_override("policy.hidden=32x24");
  EXPECT_EQ(c.get_int("planner.samples"), 7);
  EXPECT_TRUE(c.get_bool("planner.clamp_adjoint"));
  EXPECT_EQ(c.get_int_list("policy.hidden"), (Config::IntList{32, 24}));
}

TEST(Config, RejectsUnknownKeysWithSuggestion) {
  Config c = make_config();
  const std::string m = message_of([&] { c.merge_yaml("planner:\n  sample: 3\n", "my.yaml"); });
  EXPECT_NE(m.find("unknown config key 'planner.sample' in my.yaml"), std::string::npos) << m;
  EXPECT_NE(m.find("did you mean 'planner.samples'"), std::string::npos) << m;
  EXPECT_NE(message_of([&] { c.apply_override("nonsense=1"); }).find("unknown config key 'nonsense'"),
            std::string::npos);
}

TEST(Config, RejectsWrongTypesAndRanges) {
  Config c = make_config();
  std::string m = message_of([&] { c.apply_override("planner.samples=abc"); });
  EXPECT_NE(m.find("'planner.samples'"), std::string::npos) << m;
  EXPECT_NE(m.find("an integer in [1, 10000]"), std::string::npos) << m;
  m = message_of([&] { c.apply_override("planner.samples=2.5"); });
  EXPECT_NE(m.find("an integer"), std::string::npos) << m;
  m = message_of([&] { c.apply_override("planner.samples=0"); });
  EXPECT_NE(m.find("got '0'"), std::string::npos) << m;
  m = message_of([&] { c.apply_override("planner.lambda=-1"); });
  EXPECT_NE(m.find("a number in [1e-06, 1000000]"), std::string::npos) << m;
  m = message_of([&] { c.apply_override("planner.lambda=nan"); });
  EXPECT_NE(m.find("'planner.lambda'"), std::string::npos) << m;
  m = message_of([&] { c.apply_override("env=moon"); });
  EXPECT_NE(m.find("one of: pendulum, cartpole_swingup"), std::string::npos) << m;
  m = message_of([&] { c.apply_override("planner.clamp_adjoint=maybe"); });
  EXPECT_NE(m.find("true or false"), std::string::npos) << m;
  m = message_of([&] { c.apply_override("seed"); });
  EXPECT_NE(m.find("key=value"), std::string::npos) << m;
  m = message_of([&] { c.merge_yaml("planner: [1, 2\n", "bad.yaml"); });
  EXPECT_NE(m.find("malformed YAML in bad.yaml"), std::string::npos) << m;
  m = message_of([&] { c.load_file("/nonexistent/x.yaml"); });
  EXPECT_NE(m.find("/nonexistent/x.yaml"), std::string::npos) << m;
  // A rejected value leaves the previous one in place.
  EXPECT_EQ(c.get_int("planner.samples"), 20);
}

TEST(Config, YamlRoundTrip) {
  Config c = make_config();
  c.apply_override("planner.lambda=0.123456789012345");
  c.apply_override("policy.hidden=[128, 64]");
  Config d = make_config();
  d.merge_yaml(c.to_yaml(), "round trip");
  EXPECT_EQ(d.get_double("planner.lambda"), 0.123456789012345);
  EXPECT_EQ(d.get_int_list("policy.hidden"), (Config::IntList{128, 64}));
  EXPECT_EQ(d.to_yaml(), c.to_yaml());
  EXPECT_NE(c.describe().find("planner.samples"), std::string::npos);
}

TEST(Config, SelfReferentialAliasesAndDirectoriesAreClearErrors) {
  Config c = make_config();
  std::string m = message_of([&] { c.merge_yaml("planner: &p\n  inner: *p\n", "loop.yaml"); });
  EXPECT_NE(m.find("nested more than 16 levels"), std::string::npos) << m;
  m = message_of([&] { c.merge_yaml("policy:\n  hidden: &a [1, *a]\n", "list.yaml"); });
  EXPECT_NE(m.find("config key 'policy.hidden' in list.yaml"), std::string::npos) << m;
  const auto dir = std::filesystem::temp_directory_path() / "hlt_config_dir_test";
  std::filesystem::create_directories(dir);
  m = message_of([&] { c.load_file(dir.string()); });
  EXPECT_NE(m.find("it is a directory"), std::string::npos) << m;
}

TEST(Checksum, DetectsFlipsTruncationAndMissingTrailers) {
  const std::string content(1000, 'x');
  const std::string stored = with_checksum_trailer(content);
  EXPECT_EQ(verified_content(stored, "f"), content);
  for (size_t i : {size_t{0}, size_t{7}, size_t{500}, size_t{999}}) {
    std::string bad = stored;
    bad[i] ^= 1;
    EXPECT_THROW(verified_content(bad, "f"), Error) << i;
  }
  EXPECT_THROW(verified_content(stored.substr(0, 900), "f"), Error);
  EXPECT_THROW(verified_content(content, "f"), Error);
  EXPECT_NE(checksum64("abc", 3), checksum64("abd", 3));
  EXPECT_NE(checksum64("", 0), checksum64(std::string(1, '\0').data(), 1));
}

}  // namespace
}  // namespace hlt
