// hlt::ScalarLogger: TensorBoard's scalar-export layout as one CSV file per run.
//
// Every row is `wall_time,step,tag,value` (wall_time in Unix seconds, step in environment steps unless a tag
// says otherwise), the same columns TensorBoard's "download as CSV" gives for one tag, with all tags in one
// file. Each row is flushed as it is written, so a killed run loses nothing it logged. Resuming a run
// truncates the file back to the checkpoint's step so the resumed log continues exactly.
//
// Every row also goes to a TensorBoard event file in the same directory (hlt::EventFileWriter), so that
// `tensorboard --logdir runs/` shows the same tags and steps; the CSV stays the record the plots read.
#pragma once

#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "hlt/util/event_file_writer.h"

namespace hlt {

struct ScalarRow {
  double wall_time = 0;
  int64_t step = 0;
  std::string tag;
  double value = 0;
};

class ScalarLogger {
 public:
  // Opens `path` for appending (writing the header if the file is new or empty) and the event file beside it.
  // A log written before event files existed gets one holding all its rows, so the two never disagree.
  explicit ScalarLogger(const std::string& path);
  // Writes the CSV row and the event record (the value as a float, as TensorBoard stores it); a failed write
  // throws hlt::Error naming the file.
  void log(int64_t step, const std::string& tag, double value);
  const std::string& path() const { return path_; }
  const std::string& events_path() const { return events_.path(); }

  // Parses a log written by this class; throws hlt::Error on a malformed line (naming line number).
  static std::vector<ScalarRow> read(const std::string& path);
  // Rewrites `path` and the event files beside it atomically keeping only rows with step <= max_step (used on
  // resume).
  static void truncate_after(const std::string& path, int64_t max_step);

  static constexpr const char* kHeader = "wall_time,step,tag,value";

 private:
  std::string path_;
  std::ofstream out_;
  EventFileWriter events_;
};

}  // namespace hlt
