// File helpers that never leave a half-written file behind: writes go to a temporary file in the same
// directory, are flushed to disk, and are renamed over the target (rename is atomic on POSIX).
#pragma once

#include <functional>
#include <string>

namespace hlt {

// Writes `content` to `path` atomically.
void write_file_atomic(const std::string& path, const std::string& content);

// Lets `writer` fill a temporary path next to `path`, then renames it over `path`. Used for writers that
// insist on a file name of their own (torch::save, cv::FileStorage).
void write_atomic_with(const std::string& path,
                       const std::function<void(const std::string& tmp_path)>& writer);

// Reads a whole file; throws hlt::Error naming the path if it cannot be read.
std::string read_file(const std::string& path);

bool file_exists(const std::string& path);

// Creates a directory and its parents; throws if it cannot be created or is not writable.
void ensure_writable_directory(const std::string& path);

}  // namespace hlt
