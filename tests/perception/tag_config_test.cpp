#include "envs/perception/tag_config.h"

#include <gtest/gtest.h>

#include "envs/perception/pose_math.h"
#include "perception_test_support.h"

namespace hlt {
namespace {

using test::error_of;

TEST(TagConfig, ReadsTheSawyerExample) {
  const TagConfig c = test::sawyer_tags();
  EXPECT_EQ(c.family(), "tag36h11");
  ASSERT_EQ(c.tags().size(), 4u);
  EXPECT_EQ(c.at(1).name, "block");
  EXPECT_DOUBLE_EQ(c.by_name("target").size, 0.048);
  EXPECT_DOUBLE_EQ(c.by_name("block").size, 0.033);
  EXPECT_DOUBLE_EQ(c.by_name("end_effector").size, 0.033);
  EXPECT_NEAR(c.by_name("block").tag_from_object.translation().z(), -0.025, 1e-12);
  ASSERT_NE(c.reference(), nullptr);
  EXPECT_EQ(c.reference()->name, "table");
  EXPECT_TRUE(c.reference()->table_from_tag->isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_EQ(c.find(42), nullptr);
}

TEST(TagConfig, ReferencePoseTakesYawInDegrees) {
  const TagConfig c = TagConfig::parse(
      "family: tag36h11\ntags:\n  - {id: 5, name: table, size: 0.05, table_pose: [0.1, 0.2, 0.0, 90]}\n",
      "t");
  const Eigen::Isometry3d& p = *c.reference()->table_from_tag;
  EXPECT_NEAR(yaw_of(p.linear()), M_PI / 2, 1e-12);
  EXPECT_NEAR(p.translation().y(), 0.2, 1e-12);
}

TEST(TagConfig, ErrorsNameTheFileEntryAndField) {
  auto parse = [](const std::string& tags, const std::string& family = "tag36h11") {
    return error_of([&] { TagConfig::parse("family: " + family + "\ntags:\n" + tags, "tags.yaml"); });
  };
  EXPECT_NE(parse("  - {id: 1, name: a, size: 0.03}\n", "tag99h1").find("unknown AprilTag family 'tag99h1'"),
            std::string::npos);
  EXPECT_NE(parse("  - {id: 1, name: a, size: 0.03}\n  - {id: 1, name: b, size: 0.03}\n")
                .find("tags.yaml: tags[1]: id 1 appears twice"),
            std::string::npos);
  EXPECT_NE(parse("  - {id: 600, name: a, size: 0.03}\n")
                .find("tags[0]: field 'id' is 600, but tag36h11 has ids 0..586"),
            std::string::npos);
  EXPECT_NE(parse("  - {id: 1, name: a}\n").find("tags[0]: field 'size' is missing"), std::string::npos);
  EXPECT_NE(parse("  - {id: 1, name: a, size: -0.03}\n").find("field 'size' must be in (0, 10) metres"),
            std::string::npos);
  EXPECT_NE(parse("  - {id: 1, name: a, size: big}\n").find("field 'size' must be a number"),
            std::string::npos);
  EXPECT_NE(parse("  - {id: 1, name: a, size: 0.03, colour: red}\n").find("unknown field 'colour'"),
            std::string::npos);
  EXPECT_NE(parse("  - {id: 1, name: a, size: 0.03, object_offset: [0, 0]}\n")
                .find("field 'object_offset' must be a list of 3 numbers"),
            std::string::npos);
  EXPECT_NE(parse("  - {id: 1, name: a, size: 0.03, table_pose: [0, 0, 0, 0]}\n"
                  "  - {id: 2, name: b, size: 0.03, table_pose: [0, 0, 0, 0]}\n")
                .find("at most one reference tag"),
            std::string::npos);
  EXPECT_NE(error_of([] { TagConfig::parse("tags: [", "x.yaml"); }).find("x.yaml: not valid YAML"),
            std::string::npos);
  EXPECT_NE(error_of([] { TagConfig::parse("tags: []\n", "x.yaml"); }).find("field 'family' is missing"),
            std::string::npos);
  EXPECT_NE(error_of([] { TagConfig::load("/nonexistent/tags.yaml"); }).find("/nonexistent/tags.yaml"),
            std::string::npos);
}

TEST(TagConfig, UnknownIdsAndNamesAreClearErrors) {
  const TagConfig c = test::sawyer_tags();
  const std::string m = error_of([&] { c.at(7); });
  EXPECT_NE(m.find("unknown tag id 7; configured: 0 (table), 1 (block), 2 (target), 3 (end_effector)"),
            std::string::npos)
      << m;
  EXPECT_NE(error_of([&] { c.by_name("gripper"); }).find("no tag named 'gripper'"), std::string::npos);
}

}  // namespace
}  // namespace hlt
