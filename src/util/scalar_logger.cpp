#include "hlt/util/scalar_logger.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <sstream>

#include "hlt/util/error.h"
#include "hlt/util/files.h"

namespace hlt {
namespace {

double unix_seconds() {
  using namespace std::chrono;
  return duration<double>(system_clock::now().time_since_epoch()).count();
}

std::string format_row(double wall_time, int64_t step, const std::string& tag, double value) {
  // 17 significant digits: values read back are bit-identical, so resumed logs compare exactly.
  return fmt::format("{:.6f},{},{},{:.17g}\n", wall_time, step, tag, value);
}

std::string directory_of(const std::string& path) {
  const auto dir = std::filesystem::path(path).parent_path();
  return dir.empty() ? "." : dir.string();
}

}  // namespace

ScalarLogger::ScalarLogger(const std::string& path) : path_(path), events_(directory_of(path)) {
  const bool fresh = !std::filesystem::exists(path) || std::filesystem::file_size(path) == 0;
  out_.open(path, std::ios::app);
  check(out_.good(), "cannot open log {} for writing", path);
  if (fresh) {
    out_ << kHeader << '\n';
    out_.flush();
    check(out_.good(), "cannot write to log {}", path);
  } else if (events_.created()) {
    for (const auto& row : read(path))
      events_.add_scalar(row.step, row.tag, static_cast<float>(row.value), row.wall_time);
  }
}

void ScalarLogger::log(int64_t step, const std::string& tag, double value) {
  check(tag.find(',') == std::string::npos && tag.find('\n') == std::string::npos,
        "log tag '{}' must not contain commas or newlines", tag);
  const double wall_time = unix_seconds();
  out_ << format_row(wall_time, step, tag, value);
  out_.flush();
  check(out_.good(), "cannot write to log {}", path_);
  events_.add_scalar(step, tag, static_cast<float>(value), wall_time);
}

std::vector<ScalarRow> ScalarLogger::read(const std::string& path) {
  const std::string text = read_file(path);
  std::vector<ScalarRow> rows;
  // A run killed before its header was flushed leaves an empty file (or part of the header): no rows.
  if (std::string(kHeader).rfind(text, 0) == 0) return rows;
  std::istringstream in(text);
  std::string line;
  check(static_cast<bool>(std::getline(in, line)) && line == kHeader, "{} is not a scalar log (header '{}')",
        path, kHeader);
  int line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty()) continue;
    std::stringstream ss(line);
    std::string wall, step, tag, value;
    const bool ok = std::getline(ss, wall, ',') && std::getline(ss, step, ',') &&
                    std::getline(ss, tag, ',') && std::getline(ss, value);
    check(ok, "{}:{}: expected 4 comma-separated fields, got '{}'", path, line_no, line);
    try {
      rows.push_back({std::stod(wall), std::stoll(step), tag, std::stod(value)});
    } catch (const std::exception&) {
      throw Error(fmt::format("{}:{}: cannot parse '{}'", path, line_no, line));
    }
  }
  return rows;
}

void ScalarLogger::truncate_after(const std::string& path, int64_t max_step) {
  std::istringstream in(read_file(path));
  std::string line, kept;
  std::getline(in, line);
  kept = std::string(kHeader) + "\n";  // also when the header itself was cut off
  while (std::getline(in, line)) {
    // A partial last line (a run killed mid-write) lacks fields: drop it. Rows up to the checkpoint were
    // flushed before the checkpoint was written, so they are complete.
    if (std::count(line.begin(), line.end(), ',') != 3) continue;
    const auto c1 = line.find(',');
    const auto c2 = line.find(',', c1 + 1);
    int64_t step = 0;
    try {
      step = std::stoll(line.substr(c1 + 1, c2 - c1 - 1));
    } catch (const std::exception&) {
      continue;
    }
    if (step <= max_step) kept += line + "\n";
  }
  write_file_atomic(path, kept);
  EventFileWriter::truncate_after(directory_of(path), max_step);
}

}  // namespace hlt
