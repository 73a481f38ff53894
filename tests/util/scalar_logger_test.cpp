#include "hlt/util/scalar_logger.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "hlt/util/error.h"
#include "hlt/util/files.h"

namespace hlt {
namespace {

std::string temp_path(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() / "hlt_util_test";
  std::filesystem::create_directories(dir);
  auto p = dir / name;
  std::filesystem::remove(p);
  return p.string();
}

TEST(ScalarLogger, RowsParseBackExactly) {
  const std::string path = temp_path("log.csv");
  {
    ScalarLogger log(path);
    log.log(0, "train/return", -1234.5678901234567);
    log.log(200, "eval/return_mean", 1.0 / 3.0);
  }
  {
    ScalarLogger log(path);  // reopening appends, no second header
    log.log(400, "train/return", 7);
  }
  const auto rows = ScalarLogger::read(path);
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0].tag, "train/return");
  EXPECT_EQ(rows[0].value, -1234.5678901234567);
  EXPECT_EQ(rows[1].step, 200);
  EXPECT_EQ(rows[1].value, 1.0 / 3.0);
  EXPECT_EQ(rows[2].step, 400);
  EXPECT_GT(rows[0].wall_time, 1.6e9);
  const std::string text = read_file(path);
  EXPECT_EQ(text.rfind("wall_time,step,tag,value\n", 0), 0u);
}

TEST(ScalarLogger, EveryRowIsOnDiskImmediately) {
  const std::string path = temp_path("flush.csv");
  ScalarLogger log(path);
  log.log(5, "x", 1);
  // Read while the logger is still open: the row must already be there.
  EXPECT_EQ(ScalarLogger::read(path).size(), 1u);
}

TEST(ScalarLogger, TruncateAfterDropsLaterAndPartialRows) {
  const std::string path = temp_path("trunc.csv");
  {
    ScalarLogger log(path);
    for (int s = 0; s <= 10; ++s)
      log.log(s * 100, "v", s);
  }
  {
    std::ofstream out(path, std::ios::app);
    out << "1700000000.0,11";  // a row cut off by a kill
  }
  ScalarLogger::truncate_after(path, 500);
  const auto rows = ScalarLogger::read(path);
  ASSERT_EQ(rows.size(), 6u);
  EXPECT_EQ(rows.back().step, 500);
}

TEST(ScalarLogger, MalformedFilesAreReported) {
  const std::string path = temp_path("bad.csv");
  write_file_atomic(path, "wall_time,step,tag,value\n1,2,x\n");
  try {
    ScalarLogger::read(path);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.csv:2"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ScalarLogger::read(temp_path("missing.csv")), Error);
  ScalarLogger log(temp_path("tags.csv"));
  EXPECT_THROW(log.log(0, "a,b", 1), Error);
}

TEST(Files, AtomicWriteReplacesWholeFile) {
  const std::string path = temp_path("atomic.txt");
  write_file_atomic(path, "first version, long content");
  write_file_atomic(path, "second");
  EXPECT_EQ(read_file(path), "second");
  // No temporary files are left behind.
  int n = 0;
  for (auto& e : std::filesystem::directory_iterator(std::filesystem::path(path).parent_path())) {
    n += e.path().string().find(".tmp.") != std::string::npos;
  }
  EXPECT_EQ(n, 0);
  EXPECT_THROW(ensure_writable_directory("/proc/hlt_cannot_exist"), Error);
}

}  // namespace
}  // namespace hlt
