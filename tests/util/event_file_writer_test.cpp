#include "hlt/util/event_file_writer.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "hlt/util/error.h"
#include "hlt/util/files.h"
#include "util/tfevents_test_reader.h"

namespace hlt {
namespace {
namespace fs = std::filesystem;
using namespace event_file;
using namespace hlt::test;

std::string hex(std::string_view bytes) {
  std::string out;
  for (unsigned char b : bytes)
    out += fmt::format("{:02x}", b);
  return out;
}

std::string varint(uint64_t v) {
  std::string out;
  append_varint(out, v);
  return hex(out);
}

// ---- CRC-32C and the protobuf encoding ----

TEST(EventFile, Crc32cKnownVectors) {
  EXPECT_EQ(crc32c("123456789"), 0xE3069283u);
  EXPECT_EQ(crc32c(""), 0u);
  // RFC 3720 (iSCSI), appendix B.4.
  std::string zeros(32, '\0'), ones(32, '\xff'), up, down;
  for (int i = 0; i < 32; ++i) {
    up.push_back(static_cast<char>(i));
    down.push_back(static_cast<char>(31 - i));
  }
  EXPECT_EQ(crc32c(zeros), 0x8A9136AAu);
  EXPECT_EQ(crc32c(ones), 0x62A8AB43u);
  EXPECT_EQ(crc32c(up), 0x46DD794Eu);
  EXPECT_EQ(crc32c(down), 0x113FDB5Cu);
  // Chained over pieces it equals one pass.
  EXPECT_EQ(crc32c("56789", crc32c("1234")), 0xE3069283u);
}

TEST(EventFile, MaskedCrc) {
  // Values from Python's crc32c module and the formula ((crc >> 15) | (crc << 17)) + 0xa282ead8 mod 2^32.
  EXPECT_EQ(masked_crc32c("123456789"), 0xC78AB0E5u);
  EXPECT_EQ(masked_crc32c(""), 0xA282EAD8u);
  EXPECT_EQ(masked_crc32c(std::string(8, '\0')), 0x07980329u);  // the length field of an empty record
  const uint32_t crc = 0xE3069283u;
  EXPECT_EQ(masked_crc32c("123456789"), static_cast<uint32_t>(((crc >> 15) | (crc << 17)) + 0xa282ead8u));
}

TEST(EventFile, VarintEdgeCases) {
  EXPECT_EQ(varint(0), "00");
  EXPECT_EQ(varint(1), "01");
  EXPECT_EQ(varint(127), "7f");
  EXPECT_EQ(varint(128), "8001");
  EXPECT_EQ(varint(300), "ac02");
  EXPECT_EQ(varint(16383), "ff7f");
  EXPECT_EQ(varint(16384), "808001");
  EXPECT_EQ(varint(uint64_t{1} << 32), "8080808010");
  EXPECT_EQ(varint(UINT64_MAX), "ffffffffffffffffff01");
  // int64 -1 is encoded as its two's complement: ten bytes.
  EXPECT_EQ(varint(static_cast<uint64_t>(int64_t{-1})), "ffffffffffffffffff01");
}

TEST(EventFile, EncodesEventsByteForByte) {
  // wall_time 1.5 (fixed64), step 3, summary { value { tag "a" simple_value 2.0 } }.
  EXPECT_EQ(hex(encode_scalar_event(1.5, 3, "a", 2.0f)),
            "09000000000000f83f"
            "1003"
            "2a0a"
            "0a08"
            "0a0161"
            "1500000040");
  EXPECT_EQ(hex(encode_file_version_event(1.5)),
            "09000000000000f83f"
            "1a0d" +
                hex("brain.Event:2"));
  // A 200-byte tag makes the lengths two-byte varints.
  const std::string tag(200, 't');
  const std::string e = encode_scalar_event(0, 0, tag, 0);
  EXPECT_EQ(hex(e.substr(9, 2 + 6)),
            "1000"
            "2ad301"
            "0ad001");
  EXPECT_EQ(e.size(), 9 + 2 + 3 + 3 + 3 + 200 + 5u);
}

TEST(EventFile, FramesRecords) {
  const std::string r = frame_record("123456789");
  ASSERT_EQ(r.size(), 8 + 4 + 9 + 4u);
  EXPECT_EQ(hex(r.substr(0, 8)), "0900000000000000");
  EXPECT_EQ(le32(r, 8), masked_crc32c(r.substr(0, 8)));
  EXPECT_EQ(r.substr(12, 9), "123456789");
  EXPECT_EQ(le32(r, 21), 0xC78AB0E5u);
}

// ---- The writer ----

TEST(EventFileWriter, RoundTripsThroughAnIndependentCppReader) {
  const std::string dir = fresh_event_dir("roundtrip");
  const std::vector<Scalar> written = {{0, "train/episode_return", -1234.5678f},
                                       {200, "eval/return_mean", 1.0f / 3.0f},
                                       {int64_t{1} << 40, "time/wall_seconds", 3.0e38f},
                                       {-5, "weird tag/with spaces", -0.0f},
                                       {7, std::string(300, 'x'), 1e-30f}};
  std::string path;
  {
    EventFileWriter w(dir);
    EXPECT_TRUE(w.created());
    path = w.path();
    for (const auto& s : written)
      w.add_scalar(s.step, s.tag, s.value, 1.7e9 + s.step * 1e-9);
    // Nothing is buffered: the records are in the file before the writer closes.
    EXPECT_EQ(scalars_of(path), written);
  }
  EXPECT_EQ(only_event_file(dir), path);
  const std::string name = fs::path(path).filename().string();
  char host[256] = {};
  ::gethostname(host, sizeof host - 1);
  EXPECT_EQ(name.rfind("events.out.tfevents.", 0), 0u) << name;
  EXPECT_NE(name.find(fmt::format(".{}.{}.", host, ::getpid())), std::string::npos) << name;
  EXPECT_EQ(scalars_of(path), written);

  // Reopening appends to the same file without a second file_version record.
  {
    EventFileWriter w(dir);
    EXPECT_FALSE(w.created());
    EXPECT_EQ(w.path(), path);
    w.add_scalar(8, "later", 4.0f, 1.7e9);
  }
  auto all = written;
  all.push_back({8, "later", 4.0f});
  EXPECT_EQ(scalars_of(path), all);
  std::vector<DecodedEvent> events;
  ASSERT_TRUE(read_events(path, events));
  ASSERT_EQ(events.size(), all.size() + 1);
  EXPECT_DOUBLE_EQ(events[2].wall_time, 1.7e9 + 200e-9);
}

TEST(EventFileWriter, DropsARecordCutOffByAKillBeforeAppending) {
  const std::string dir = fresh_event_dir("cutoff");
  std::string path;
  {
    EventFileWriter w(dir);
    path = w.path();
    w.add_scalar(1, "v", 1, 1.7e9);
  }
  const std::string partial = frame_record(encode_scalar_event(1.7e9, 2, "v", 2));
  {
    std::ofstream out(path, std::ios::app | std::ios::binary);
    out << partial.substr(0, partial.size() - 3);
  }
  {
    EventFileWriter w(dir);
    w.add_scalar(3, "v", 3, 1.7e9);
  }
  EXPECT_EQ(scalars_of(path), (std::vector<Scalar>{{1, "v", 1}, {3, "v", 3}}));
}

TEST(EventFileWriter, CorruptRecordsAreReportedNotSkipped) {
  const std::string dir = fresh_event_dir("corrupt");
  std::string path;
  {
    EventFileWriter w(dir);
    path = w.path();
    w.add_scalar(1, "v", 1, 1.7e9);
    w.add_scalar(2, "v", 2, 1.7e9);
  }
  std::string content = read_file(path);
  content[content.size() - 8] ^= 1;  // inside the last record's value
  write_file_atomic(path, content);
  try {
    EventFileWriter::truncate_after(dir, 10);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("CRC"), std::string::npos) << e.what();
  }
  EXPECT_EQ(read_file(path), content);
}

// A write that fails (here: the file size limit, as a full disk would) throws naming the file. In a child
// process, so that the limit and the ignored SIGXFSZ stay there. Exit code 42: thrown, naming the file.
void fill_event_file(const std::string& dir) {
  limit_file_size(200);
  std::string path;
  try {
    EventFileWriter w(dir);
    path = w.path();
    for (int i = 0; i < 100; ++i)
      w.add_scalar(i, "train/episode_return", 1, 1.7e9);
  } catch (const Error& e) {
    std::fprintf(stderr, "%s\n", e.what());
    std::_Exit(!path.empty() && std::string(e.what()).find(path) != std::string::npos ? 42 : 43);
  }
  std::_Exit(44);
}

TEST(EventFileWriter, FailedWriteThrowsNamingTheFile) {
  const std::string dir = fresh_event_dir("failed_write");
  EXPECT_EXIT(fill_event_file(dir), ::testing::ExitedWithCode(42),
              "cannot write to TensorBoard event file .*File too large");
}

// ---- The independent reader: Python's protobuf runtime and crc32c module ----

std::string source_dir() {
  if (const char* env = std::getenv("HLT_SOURCE_DIR")) return env;
  return fs::path(__FILE__).parent_path().parent_path().parent_path().string();
}

std::pair<int, std::string> run(const std::string& command) {
  FILE* pipe = ::popen(command.c_str(), "r");
  if (!pipe) return {-1, ""};
  std::string out;
  char buf[4096];
  while (size_t n = std::fread(buf, 1, sizeof buf, pipe))
    out.append(buf, n);
  const int status = ::pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

TEST(EventFileWriter, PythonProtobufReaderAgrees) {
  const char* python = "/usr/bin/python3";
  if (run(fmt::format("{} -c 'import google.protobuf, crc32c' 2>/dev/null", python)).first != 0) {
    GTEST_SKIP() << python << " lacks the google.protobuf or crc32c module: install python3-protobuf and "
                 << "python3-crc32c (scripts/setup.sh does)";
  }
  const std::string script = source_dir() + "/tests/util/read_tfevents.py";
  ASSERT_TRUE(fs::exists(script)) << script;
  const std::string dir = fresh_event_dir("python");
  const std::vector<Scalar> written = {{0, "train/episode_return", -1234.5678f},
                                       {200, "eval/return_mean", 1.0f / 3.0f},
                                       {int64_t{1} << 40, "time/wall_seconds", 1e30f},
                                       {-5, "sac/alpha", -0.0f},
                                       {7, std::string(300, 'x'), 1e-30f}};
  std::vector<Scalar> expected = written;
  std::string path;
  {
    EventFileWriter w(dir);
    path = w.path();
    for (const auto& s : written)
      w.add_scalar(s.step, s.tag, s.value, 1.7e9);
    for (int s = 4; s < 40; ++s) {
      w.add_scalar(s * 100, "loss/critic", 1.0f / s, 1.7e9 + s);
      expected.push_back({s * 100, "loss/critic", 1.0f / s});
    }
  }
  const std::string err = dir + "/stderr.txt";
  const auto [code, out] = run(fmt::format("{} {} {} 2>{}", python, script, path, err));
  ASSERT_EQ(code, 0) << out << read_file(err);
  std::vector<Scalar> read;
  std::istringstream lines(out);
  std::string line;
  while (std::getline(lines, line)) {
    // The tag may hold commas; step and value cannot.
    const auto c1 = line.find(','), c2 = line.rfind(',');
    ASSERT_TRUE(c1 != std::string::npos && c2 > c1) << line;
    read.push_back({std::stoll(line.substr(0, c1)), line.substr(c1 + 1, c2 - c1 - 1),
                    static_cast<float>(std::stod(line.substr(c2 + 1)))});
  }
  ASSERT_EQ(read.size(), 41u);
  EXPECT_EQ(read, expected);

  // And the reader is not blind: a flipped bit fails its CRC check.
  std::string content = read_file(path);
  content[content.size() / 2] ^= 0x10;
  write_file_atomic(path, content);
  const auto [bad_code, bad_out] = run(fmt::format("{} {} {} 2>&1", python, script, path));
  EXPECT_EQ(bad_code, 1) << bad_out;
  EXPECT_NE(bad_out.find("CRC mismatch"), std::string::npos) << bad_out;
}

}  // namespace
}  // namespace hlt
