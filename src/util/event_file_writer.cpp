#include "hlt/util/event_file_writer.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>

#include "hlt/util/error.h"
#include "hlt/util/files.h"

namespace hlt {
namespace fs = std::filesystem;

namespace event_file {
namespace {

constexpr std::array<uint32_t, 256> make_crc32c_table() {
  std::array<uint32_t, 256> table{};
  for (uint32_t i = 0; i < 256; ++i) {
    uint32_t c = i;
    for (int k = 0; k < 8; ++k)
      c = (c & 1) ? (c >> 1) ^ 0x82F63B78u : c >> 1;  // Castagnoli's polynomial, bit-reversed
    table[i] = c;
  }
  return table;
}
constexpr auto kCrc32cTable = make_crc32c_table();

constexpr uint32_t kMaskDelta = 0xa282ead8u;

// Protobuf wire types.
constexpr int kVarint = 0, kFixed64 = 1, kLengthDelimited = 2, kFixed32 = 5;

void append_key(std::string& out, int field, int wire_type) {
  append_varint(out, static_cast<uint64_t>(field) << 3 | wire_type);
}

// Byte by byte rather than memcpy so that the files are little-endian whatever the host is.
void append_le(std::string& out, uint64_t bits, int bytes) {
  for (int i = 0; i < bytes; ++i)
    out.push_back(static_cast<char>(bits >> (8 * i) & 0xff));
}

void append_double(std::string& out, int field, double v) {
  uint64_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  append_key(out, field, kFixed64);
  append_le(out, bits, 8);
}

void append_float(std::string& out, int field, float v) {
  uint32_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  append_key(out, field, kFixed32);
  append_le(out, bits, 4);
}

void append_bytes(std::string& out, int field, std::string_view bytes) {
  append_key(out, field, kLengthDelimited);
  append_varint(out, bytes.size());
  out.append(bytes);
}

uint64_t read_le(std::string_view s, size_t at, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i)
    v |= static_cast<uint64_t>(static_cast<unsigned char>(s[at + i])) << (8 * i);
  return v;
}

double unix_seconds() {
  using namespace std::chrono;
  return duration<double>(system_clock::now().time_since_epoch()).count();
}

}  // namespace

uint32_t crc32c(std::string_view data, uint32_t crc) {
  crc = ~crc;
  for (unsigned char b : data)
    crc = kCrc32cTable[(crc ^ b) & 0xff] ^ (crc >> 8);
  return ~crc;
}

uint32_t masked_crc32c(std::string_view data) {
  const uint32_t crc = crc32c(data);
  return ((crc >> 15) | (crc << 17)) + kMaskDelta;
}

void append_varint(std::string& out, uint64_t value) {
  while (value >= 0x80) {
    out.push_back(static_cast<char>((value & 0x7f) | 0x80));
    value >>= 7;
  }
  out.push_back(static_cast<char>(value));
}

std::string encode_file_version_event(double wall_time) {
  std::string event;
  append_double(event, 1, wall_time);
  append_bytes(event, 3, "brain.Event:2");
  return event;
}

std::string encode_scalar_event(double wall_time, int64_t step, const std::string& tag, float value) {
  std::string summary_value;
  append_bytes(summary_value, 1, tag);
  append_float(summary_value, 2, value);
  std::string summary;
  append_bytes(summary, 1, summary_value);
  std::string event;
  append_double(event, 1, wall_time);
  // Written even when 0 (proto3 may omit it): explicit steps make the files easier to check by eye.
  append_key(event, 2, kVarint);
  append_varint(event, static_cast<uint64_t>(step));  // int64: negative steps take ten bytes, as in protobuf
  append_bytes(event, 5, summary);
  return event;
}

std::string frame_record(std::string_view data) {
  std::string header;
  append_le(header, data.size(), 8);
  std::string record = header;
  append_le(record, masked_crc32c(header), 4);
  record.append(data);
  append_le(record, masked_crc32c(data), 4);
  return record;
}

SplitRecords split_records(std::string_view content, const std::string& path) {
  SplitRecords out;
  size_t at = 0;
  while (content.size() - at >= 12) {
    const std::string_view header = content.substr(at, 8);
    check(read_le(content, at + 8, 4) == masked_crc32c(header),
          "{}: corrupt TensorBoard record at byte {} (length CRC mismatch)", path, at);
    const uint64_t length = read_le(content, at, 8);
    if (length > content.size() - at - 12 || content.size() - at - 12 - length < 4) break;  // cut off
    const std::string_view data = content.substr(at + 12, length);
    check(read_le(content, at + 12 + length, 4) == masked_crc32c(data),
          "{}: corrupt TensorBoard record at byte {} (data CRC mismatch)", path, at);
    out.records.emplace_back(data);
    at += 12 + length + 4;
  }
  out.valid_bytes = at;
  return out;
}

EventHeader decode_event_header(std::string_view event, const std::string& path) {
  EventHeader h;
  size_t at = 0;
  auto fail = [&] {
    throw Error(fmt::format("{}: malformed Event record (byte {} of {})", path, at, event.size()));
  };
  auto varint = [&] {
    uint64_t v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      if (at >= event.size()) fail();
      const auto b = static_cast<unsigned char>(event[at++]);
      v |= static_cast<uint64_t>(b & 0x7f) << shift;
      if (!(b & 0x80)) return v;
    }
    fail();
    return v;
  };
  auto skip = [&](uint64_t n) {
    if (n > event.size() - at) fail();
    at += n;
  };
  while (at < event.size()) {
    const uint64_t key = varint();
    const uint64_t field = key >> 3;
    switch (key & 7) {
      case kVarint: {
        const uint64_t v = varint();
        if (field == 2) h.step = static_cast<int64_t>(v);
        break;
      }
      case kFixed64:
        skip(8);
        break;
      case kLengthDelimited:
        skip(varint());
        if (field == 3) h.file_version = true;
        break;
      case kFixed32:
        skip(4);
        break;
      default:
        fail();
    }
  }
  return h;
}

bool is_event_file_name(const std::string& file_name) {
  // write_file_atomic's temporaries (<name>.tmp.<pid>) are not event files, though TensorBoard would read
  // them.
  return file_name.rfind("events.out.tfevents.", 0) == 0 && file_name.find(".tmp.") == std::string::npos;
}

}  // namespace event_file

namespace {

std::string new_file_name() {
  // TensorFlow's writers number theirs per process; the counter keeps two writers in one second apart.
  static std::atomic<int> counter{0};
  char host[256] = "localhost";
  if (::gethostname(host, sizeof host) != 0) std::strcpy(host, "localhost");
  host[sizeof host - 1] = '\0';
  const auto now =
      std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch())
          .count();
  return fmt::format("events.out.tfevents.{}.{}.{}.{}", now, host, static_cast<long>(::getpid()), counter++);
}

}  // namespace

EventFileWriter::EventFileWriter(const std::string& dir) {
  check(fs::is_directory(dir), "cannot write TensorBoard events to {}: not a directory", dir);
  const auto existing = files_in(dir);
  bool needs_version = true;
  if (!existing.empty()) {
    path_ = existing.back();
    const std::string content = read_file(path_);
    const auto split = event_file::split_records(content, path_);
    if (split.valid_bytes < content.size()) write_file_atomic(path_, content.substr(0, split.valid_bytes));
    needs_version = split.valid_bytes == 0;
    fd_ = ::open(path_.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
  } else {
    path_ = (fs::path(dir) / new_file_name()).string();
    fd_ = ::open(path_.c_str(), O_WRONLY | O_APPEND | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    created_ = true;
  }
  check(fd_ >= 0, "cannot open TensorBoard event file {}: {}", path_, std::strerror(errno));
  if (needs_version) write_record(event_file::encode_file_version_event(event_file::unix_seconds()));
}

EventFileWriter::~EventFileWriter() {
  if (fd_ >= 0) ::close(fd_);
}

EventFileWriter::EventFileWriter(EventFileWriter&& other) noexcept
    : path_(std::move(other.path_)), fd_(other.fd_), created_(other.created_) {
  other.fd_ = -1;
}

EventFileWriter& EventFileWriter::operator=(EventFileWriter&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    path_ = std::move(other.path_);
    fd_ = other.fd_;
    created_ = other.created_;
    other.fd_ = -1;
  }
  return *this;
}

void EventFileWriter::add_scalar(int64_t step, const std::string& tag, float value, double wall_time) {
  write_record(event_file::encode_scalar_event(wall_time, step, tag, value));
}

void EventFileWriter::write_record(std::string_view data) {
  check(fd_ >= 0, "TensorBoard event file {} is closed", path_);
  const std::string record = event_file::frame_record(data);
  size_t done = 0;
  while (done < record.size()) {
    const ssize_t n = ::write(fd_, record.data() + done, record.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      throw Error(fmt::format("cannot write to TensorBoard event file {}: {}", path_,
                              n < 0 ? std::strerror(errno) : "nothing written"));
    }
    done += static_cast<size_t>(n);
  }
}

std::vector<std::string> EventFileWriter::files_in(const std::string& dir) {
  std::vector<std::string> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    std::error_code type_ec;
    if (entry.is_regular_file(type_ec) && event_file::is_event_file_name(entry.path().filename().string()))
      files.push_back(entry.path().string());
  }
  check(!ec, "cannot list {}: {}", dir, ec.message());
  std::sort(files.begin(), files.end());
  return files;
}

void EventFileWriter::truncate_after(const std::string& dir, int64_t max_step) {
  for (const auto& path : files_in(dir)) {
    const std::string content = read_file(path);
    const auto split = event_file::split_records(content, path);
    bool changed = split.valid_bytes < content.size();
    std::string kept;
    for (const auto& record : split.records) {
      const auto h = event_file::decode_event_header(record, path);
      if (h.file_version || h.step <= max_step) {
        kept += event_file::frame_record(record);
      } else {
        changed = true;
      }
    }
    if (changed) write_file_atomic(path, kept);
  }
}

}  // namespace hlt
