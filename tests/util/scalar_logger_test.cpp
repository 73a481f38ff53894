#include "hlt/util/scalar_logger.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "hlt/util/error.h"
#include "hlt/util/files.h"
#include "util/tfevents_test_reader.h"

namespace hlt {
namespace {
using namespace hlt::test;
using event_file::encode_file_version_event;
using event_file::encode_scalar_event;
using event_file::frame_record;

// A directory of its own per file: every log writes a TensorBoard event file beside it.
std::string temp_path(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() / "hlt_scalar_logger_test" / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return (dir / name).string();
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

TEST(ScalarLogger, ALogKilledBeforeItsHeaderReadsAsEmptyAndResumes) {
  // A run killed in its first instant leaves an empty log, or part of the header.
  for (const std::string& content : {std::string(), std::string("wall_time,st")}) {
    const std::string path = temp_path("cut_header.csv");
    write_file_atomic(path, content);
    EXPECT_TRUE(ScalarLogger::read(path).empty());
    ScalarLogger::truncate_after(path, -1);
    {
      ScalarLogger log(path);
      log.log(3, "x", 1.5);
    }
    const auto rows = ScalarLogger::read(path);
    ASSERT_EQ(rows.size(), 1u);
    EXPECT_EQ(rows[0].step, 3);
  }
  // Something else without a header is still not a log.
  const std::string other = temp_path("not_a_log.csv");
  write_file_atomic(other, "step,value\n1,2\n");
  EXPECT_THROW(ScalarLogger::read(other), Error);
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

std::vector<Scalar> scalars_of_csv(const std::string& path) {
  std::vector<Scalar> out;
  for (const auto& r : ScalarLogger::read(path))
    out.push_back({r.step, r.tag, static_cast<float>(r.value)});
  return out;
}

// As EventFileWriter.FailedWriteThrowsNamingTheFile, for each of the two files. `limit` is the file size
// limit in bytes; exit code 42: thrown, naming the file `expected` (scalars.csv or the event file).
void fill_scalar_log(const std::string& dir, rlim_t limit, const std::string& expected) {
  limit_file_size(limit);
  try {
    ScalarLogger log(dir + "/scalars.csv");
    for (int i = 0; i < 100; ++i)
      log.log(i, "train/episode_return", 1);
  } catch (const Error& e) {
    std::fprintf(stderr, "%s\n", e.what());
    std::_Exit(std::string(e.what()).find(expected) != std::string::npos ? 42 : 43);
  }
  std::_Exit(44);
}

TEST(ScalarLogger, FailedWriteThrowsNamingTheFile) {
  // Fresh: an event record is longer than a CSV row, so the event file reaches the limit first.
  const std::string dir = fresh_event_dir("failed_log");
  EXPECT_EXIT(fill_scalar_log(dir, 300, "events.out.tfevents."), ::testing::ExitedWithCode(42),
              "cannot write to TensorBoard event file");
  // A CSV just below the limit beside an event file holding only its header: the CSV fills first.
  const std::string dir2 = fresh_event_dir("failed_csv");
  std::string csv = std::string(ScalarLogger::kHeader) + "\n";
  for (int i = 0; i < 11; ++i)
    csv += fmt::format("1700000000.000000,{},v,1\n", i);
  write_file_atomic(dir2 + "/scalars.csv", csv);
  EventFileWriter{dir2};
  ASSERT_LT(csv.size(), 300u);
  ASSERT_GT(csv.size(), 300u - 40);
  EXPECT_EXIT(fill_scalar_log(dir2, 300, dir2 + "/scalars.csv"), ::testing::ExitedWithCode(42),
              "cannot write to log");
}

// ---- Through ScalarLogger, as the trainer uses it ----

TEST(ScalarLogger, WritesEveryRowToTheEventFileToo) {
  const std::string dir = fresh_event_dir("logger");
  const std::string csv = dir + "/scalars.csv";
  {
    ScalarLogger log(csv);
    for (int s = 0; s < 5; ++s) {
      log.log(s * 100, "train/episode_return", s * 1.1);
      log.log(s * 100, "loss/critic", 1.0 / (s + 1));
    }
    EXPECT_EQ(log.events_path(), only_event_file(dir));
    EXPECT_EQ(scalars_of(log.events_path()).size(), 10u);  // on disk while the logger is open
  }
  const auto from_csv = scalars_of_csv(csv);
  ASSERT_EQ(from_csv.size(), 10u);
  EXPECT_EQ(scalars_of(only_event_file(dir)), from_csv);
  // The wall times agree with the CSV's (which has microseconds).
  std::vector<DecodedEvent> events;
  ASSERT_TRUE(read_events(only_event_file(dir), events));
  const auto rows = ScalarLogger::read(csv);
  for (size_t i = 0; i < rows.size(); ++i)
    EXPECT_NEAR(events[i + 1].wall_time, rows[i].wall_time, 1e-6);
}

TEST(ScalarLogger, ResumeTruncatesBothLogsToTheCheckpoint) {
  const std::string dir = fresh_event_dir("resume");
  const std::string csv = dir + "/scalars.csv";
  std::string events_path;
  {
    ScalarLogger log(csv);
    events_path = log.events_path();
    for (int s = 0; s <= 10; ++s) {
      log.log(s * 100, "v", s);
      log.log(s * 100, "w", -s);
    }
  }
  // The kill cut the last record of each file short.
  {
    std::ofstream out(csv, std::ios::app);
    out << "1700000000.0,11";
    const std::string r = frame_record(encode_scalar_event(1.7e9, 1100, "v", 11));
    std::ofstream ev(events_path, std::ios::app | std::ios::binary);
    ev << r.substr(0, 20);
  }
  ScalarLogger::truncate_after(csv, 500);
  EXPECT_EQ(only_event_file(dir), events_path);
  const auto kept = scalars_of(events_path);
  ASSERT_EQ(kept.size(), 12u);
  EXPECT_EQ(kept.back(), (Scalar{500, "w", -5}));
  EXPECT_EQ(kept, scalars_of_csv(csv));
  // The resumed run appends to the same file; TensorBoard sees one continuous series.
  {
    ScalarLogger log(csv);
    EXPECT_EQ(log.events_path(), events_path);
    log.log(600, "v", 6.5);
  }
  const auto resumed = scalars_of(events_path);
  ASSERT_EQ(resumed.size(), 13u);
  EXPECT_EQ(resumed.back(), (Scalar{600, "v", 6.5f}));
  EXPECT_EQ(resumed, scalars_of_csv(csv));
  // Truncating again to the same step changes nothing; to -1 (no checkpoint) keeps only the file header.
  const std::string before = read_file(events_path);
  ScalarLogger::truncate_after(csv, 600);
  EXPECT_EQ(read_file(events_path), before);
  ScalarLogger::truncate_after(csv, -1);
  EXPECT_TRUE(scalars_of(events_path).empty());
  EXPECT_TRUE(scalars_of_csv(csv).empty());
}

TEST(ScalarLogger, TruncatesEveryEventFileInTheDirectory) {
  // A run directory may hold several event files (written by another tool or an older writer); TensorBoard
  // merges them, so every one must lose its records past the checkpoint.
  const std::string dir = fresh_event_dir("several");
  const std::string csv = dir + "/scalars.csv";
  {
    ScalarLogger log(csv);
    log.log(100, "v", 1);
    log.log(300, "v", 3);
  }
  const std::string other = dir + "/events.out.tfevents.1000000000.elsewhere.1.0";
  write_file_atomic(other, frame_record(encode_file_version_event(1.7e9)) +
                               frame_record(encode_scalar_event(1.7e9, 200, "u", 2)) +
                               frame_record(encode_scalar_event(1.7e9, 400, "u", 4)));
  ScalarLogger::truncate_after(csv, 250);
  EXPECT_EQ(scalars_of(other), (std::vector<Scalar>{{200, "u", 2}}));
  const auto files = EventFileWriter::files_in(dir);
  ASSERT_EQ(files.size(), 2u);
  EXPECT_EQ(files[0], other);  // sorted by name: the older file first
  EXPECT_EQ(scalars_of(files[1]), (std::vector<Scalar>{{100, "v", 1}}));
}

TEST(ScalarLogger, ALogWithoutEventFilesGetsOneWithAllItsRows) {
  // Runs started before event files existed: resuming one must not leave TensorBoard with only the tail.
  const std::string dir = fresh_event_dir("backfill");
  const std::string csv = dir + "/scalars.csv";
  write_file_atomic(csv, "wall_time,step,tag,value\n1700000000.250000,0,v,1.5\n1700000001.000000,100,w,-2\n");
  {
    ScalarLogger log(csv);
    log.log(200, "v", 3);
  }
  const std::string path = only_event_file(dir);
  EXPECT_EQ(scalars_of(path), (std::vector<Scalar>{{0, "v", 1.5f}, {100, "w", -2}, {200, "v", 3}}));
  std::vector<DecodedEvent> events;
  ASSERT_TRUE(read_events(path, events));
  EXPECT_DOUBLE_EQ(events[1].wall_time, 1700000000.25);
}

}  // namespace
}  // namespace hlt
