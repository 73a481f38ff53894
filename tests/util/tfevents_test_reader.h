// A TensorBoard event-file reader of the tests' own, written from the format description rather than from
// hlt::EventFileWriter: it decodes every field it meets and fails the test on anything it does not expect.
#pragma once

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>

#include <cstring>
#include <filesystem>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include "hlt/util/event_file_writer.h"
#include "hlt/util/files.h"

namespace hlt::test {

// An empty directory of its own under the temp directory (event files are found by listing directories).
inline std::string fresh_event_dir(const std::string& name) {
  const auto p = std::filesystem::temp_directory_path() / "hlt_event_test" / name;
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p.string();
}

inline uint32_t le32(std::string_view s, size_t at) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i)
    v |= static_cast<uint32_t>(static_cast<unsigned char>(s[at + i])) << (8 * i);
  return v;
}

struct ScalarValue {
  std::string tag;
  float value = 0;
};

struct DecodedEvent {
  double wall_time = 0;
  int64_t step = 0;
  bool has_step = false;
  std::string file_version;
  bool has_summary = false;
  std::vector<ScalarValue> values;
};

struct Cursor {
  std::string_view s;
  size_t at = 0;
  bool ok = true;

  bool done() const { return at >= s.size() || !ok; }
  uint64_t varint() {
    uint64_t v = 0;
    for (int shift = 0; shift < 70; shift += 7) {
      if (at >= s.size()) break;
      const auto b = static_cast<unsigned char>(s[at++]);
      v |= static_cast<uint64_t>(b & 0x7f) << shift;
      if (!(b & 0x80)) return v;
    }
    ok = false;
    return 0;
  }
  uint64_t fixed(int bytes) {
    if (s.size() - at < static_cast<size_t>(bytes)) {
      ok = false;
      return 0;
    }
    uint64_t v = 0;
    for (int i = 0; i < bytes; ++i)
      v |= static_cast<uint64_t>(static_cast<unsigned char>(s[at++])) << (8 * i);
    return v;
  }
  std::string_view bytes() {
    const uint64_t n = varint();
    if (!ok || s.size() - at < n) {
      ok = false;
      return {};
    }
    const auto out = s.substr(at, n);
    at += n;
    return out;
  }
};

inline ::testing::AssertionResult decode_value(std::string_view bytes, ScalarValue& out) {
  Cursor c{bytes};
  bool has_value = false;
  while (!c.done()) {
    const uint64_t key = c.varint();
    if (key == (1 << 3 | 2)) {
      out.tag = std::string(c.bytes());
    } else if (key == (2 << 3 | 5)) {
      const auto bits = static_cast<uint32_t>(c.fixed(4));
      std::memcpy(&out.value, &bits, 4);
      has_value = true;
    } else {
      return ::testing::AssertionFailure() << "Summary.Value: unexpected key " << key;
    }
  }
  if (!c.ok) return ::testing::AssertionFailure() << "Summary.Value: truncated";
  if (!has_value) return ::testing::AssertionFailure() << "Summary.Value without simple_value";
  return ::testing::AssertionSuccess();
}

inline ::testing::AssertionResult decode_event(std::string_view bytes, DecodedEvent& e) {
  Cursor c{bytes};
  while (!c.done()) {
    const uint64_t key = c.varint();
    if (key == (1 << 3 | 1)) {
      const uint64_t bits = c.fixed(8);
      std::memcpy(&e.wall_time, &bits, 8);
    } else if (key == (2 << 3 | 0)) {
      e.step = static_cast<int64_t>(c.varint());
      e.has_step = true;
    } else if (key == (3 << 3 | 2)) {
      e.file_version = std::string(c.bytes());
    } else if (key == (5 << 3 | 2)) {
      e.has_summary = true;
      Cursor summary{c.bytes()};
      while (!summary.done()) {
        if (summary.varint() != (1 << 3 | 2))
          return ::testing::AssertionFailure() << "Summary: unexpected key";
        ScalarValue v;
        const auto r = decode_value(summary.bytes(), v);
        if (!r) return r;
        e.values.push_back(v);
      }
      if (!summary.ok) return ::testing::AssertionFailure() << "Summary: truncated";
    } else {
      return ::testing::AssertionFailure() << "Event: unexpected key " << key;
    }
  }
  if (!c.ok) return ::testing::AssertionFailure() << "Event: truncated";
  return ::testing::AssertionSuccess();
}

// Every record of a file, both CRCs checked; the whole file must be records.
inline ::testing::AssertionResult read_events(const std::string& path, std::vector<DecodedEvent>& out) {
  const std::string content = read_file(path);
  size_t at = 0;
  while (at < content.size()) {
    if (content.size() - at < 12) return ::testing::AssertionFailure() << "header cut off at " << at;
    uint64_t length = 0;
    for (int i = 0; i < 8; ++i)
      length |= static_cast<uint64_t>(static_cast<unsigned char>(content[at + i])) << (8 * i);
    if (le32(content, at + 8) != event_file::masked_crc32c(std::string_view(content).substr(at, 8)))
      return ::testing::AssertionFailure() << "length CRC mismatch at " << at;
    if (content.size() - at - 12 < length + 4) return ::testing::AssertionFailure() << "cut off at " << at;
    const std::string_view data = std::string_view(content).substr(at + 12, length);
    if (le32(content, at + 12 + length) != event_file::masked_crc32c(data))
      return ::testing::AssertionFailure() << "data CRC mismatch at " << at;
    DecodedEvent e;
    auto r = decode_event(data, e);
    if (!r) return r << " (record at " << at << ")";
    out.push_back(e);
    at += 16 + length;
  }
  return ::testing::AssertionSuccess();
}

struct Scalar {
  int64_t step;
  std::string tag;
  float value;
  bool operator==(const Scalar& o) const {
    return step == o.step && tag == o.tag && std::memcmp(&value, &o.value, sizeof value) == 0;
  }
};
inline std::ostream& operator<<(std::ostream& os, const Scalar& s) {
  return os << s.step << "," << s.tag << "," << s.value;
}

// The scalars of a file, after checking that it opens with exactly one file_version record.
inline std::vector<Scalar> scalars_of(const std::string& path) {
  std::vector<DecodedEvent> events;
  EXPECT_TRUE(read_events(path, events)) << path;
  std::vector<Scalar> out;
  for (size_t i = 0; i < events.size(); ++i) {
    const auto& e = events[i];
    EXPECT_GT(e.wall_time, 1.6e9) << "record " << i;
    if (i == 0) {
      EXPECT_EQ(e.file_version, "brain.Event:2");
      EXPECT_FALSE(e.has_summary);
      continue;
    }
    EXPECT_EQ(e.file_version, "") << "record " << i;
    EXPECT_TRUE(e.has_summary && e.has_step) << "record " << i;
    EXPECT_EQ(e.values.size(), 1u) << "record " << i;
    for (const auto& v : e.values)
      out.push_back({e.step, v.tag, v.value});
  }
  return out;
}

inline std::string only_event_file(const std::string& dir) {
  const auto files = EventFileWriter::files_in(dir);
  EXPECT_EQ(files.size(), 1u) << dir;
  return files.empty() ? "" : files[0];
}

// For tests of failed writes, in a death test's child: the size limit stands in for a full disk.
inline void limit_file_size(rlim_t bytes) {
  const rlimit limit{bytes, bytes};
  ::setrlimit(RLIMIT_FSIZE, &limit);
  ::signal(SIGXFSZ, SIG_IGN);
}

}  // namespace hlt::test
