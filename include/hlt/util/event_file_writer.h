// hlt::EventFileWriter: writes scalars as TensorBoard event files (`events.out.tfevents.*`: TFRecord framing
// around serialised tensorflow.Event protos), so `tensorboard --logdir runs/` reads a run without TensorFlow.
//
// The protobuf wire format and CRC-32C are encoded here by hand: three message types with five fields do not
// justify a protobuf dependency. The `event_file` functions are the building blocks, public for the tests.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace hlt {

namespace event_file {

// CRC-32C (Castagnoli), the checksum TFRecord uses; `crc` chains calls over consecutive pieces.
uint32_t crc32c(std::string_view data, uint32_t crc = 0);
// TFRecord stores masked CRCs so that a CRC computed over data that itself contains CRCs stays well mixed.
uint32_t masked_crc32c(std::string_view data);

void append_varint(std::string& out, uint64_t value);

// Serialised tensorflow.Event messages.
std::string encode_file_version_event(double wall_time);
std::string encode_scalar_event(double wall_time, int64_t step, const std::string& tag, float value);

// One TFRecord: length, masked CRC of the length, `data`, masked CRC of `data`.
std::string frame_record(std::string_view data);

struct SplitRecords {
  std::vector<std::string> records;  // the payloads (serialised Events)
  size_t valid_bytes = 0;  // bytes of complete records; less than the content if its tail is cut off
};
// Splits a file's content into records, verifying both CRCs of each. A record cut off at the end (a run
// killed mid-write) ends the list; a complete record with a wrong CRC is corruption and throws hlt::Error
// naming `path` and the byte offset.
SplitRecords split_records(std::string_view content, const std::string& path);

struct EventHeader {
  int64_t step = 0;           // 0 when absent, as protobuf defines
  bool file_version = false;  // the record that opens a file
};
// Reads the fields truncation needs from a serialised Event; throws hlt::Error on malformed bytes.
EventHeader decode_event_header(std::string_view event, const std::string& path);

bool is_event_file_name(const std::string& file_name);

}  // namespace event_file

class EventFileWriter {
 public:
  // Appends to the newest event file in `dir`, so a resumed run continues its own file, or creates one named
  // as TensorFlow names them (events.out.tfevents.<unix time>.<hostname>.<pid>.<n>). A record cut off by a
  // kill at the end of the existing file is dropped first, so appending cannot bury it mid-file.
  explicit EventFileWriter(const std::string& dir);
  ~EventFileWriter();
  EventFileWriter(const EventFileWriter&) = delete;
  EventFileWriter& operator=(const EventFileWriter&) = delete;
  EventFileWriter(EventFileWriter&& other) noexcept;
  EventFileWriter& operator=(EventFileWriter&& other) noexcept;

  // Written with one write(2) each and nothing buffered in the process: a killed run loses nothing it logged.
  // A failed or short write throws hlt::Error naming the file.
  void add_scalar(int64_t step, const std::string& tag, float value, double wall_time);

  const std::string& path() const { return path_; }
  // True if the constructor made a new file (there was none in the directory).
  bool created() const { return created_; }

  // The event files in `dir`, sorted by name (which is by creation time), as full paths.
  static std::vector<std::string> files_in(const std::string& dir);
  // Rewrites every event file in `dir` atomically, keeping its file_version record and the records with
  // step <= max_step (used on resume, with the checkpoint's step). Files that would not change are left
  // alone.
  static void truncate_after(const std::string& dir, int64_t max_step);

 private:
  void write_record(std::string_view data);

  std::string path_;
  int fd_ = -1;
  bool created_ = false;
};

}  // namespace hlt
