#include "hlt/util/files.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "hlt/util/error.h"

namespace hlt {
namespace fs = std::filesystem;

namespace {

std::string temp_path_for(const std::string& path) {
  return fmt::format("{}.tmp.{}", path, static_cast<long>(::getpid()));
}

void fsync_path(const std::string& path) {
  int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

}  // namespace

void write_atomic_with(const std::string& path, const std::function<void(const std::string&)>& writer) {
  const std::string tmp = temp_path_for(path);
  try {
    writer(tmp);
  } catch (...) {
    std::remove(tmp.c_str());
    throw;
  }
  fsync_path(tmp);
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    std::remove(tmp.c_str());
    throw Error(fmt::format("cannot move {} into place: {}", path, reason));
  }
}

// Fault injection for the crash tests: HLT_TEST_KILL_WRITING=NAME[:N] makes the process SIGKILL itself
// halfway through its N-th (default first) atomic write of a file named NAME, as a power cut or kill -9
// would at the worst moment.
void maybe_die_writing(const std::string& path, std::ofstream& out, const std::string& content) {
  static const char* spec = std::getenv("HLT_TEST_KILL_WRITING");
  if (spec == nullptr) return;
  static int writes = 0;
  const std::string s(spec);
  const size_t colon = s.find(':');
  const std::string name = s.substr(0, colon);
  const int nth = colon == std::string::npos ? 1 : std::atoi(s.c_str() + colon + 1);
  if (fs::path(path).filename() != name || ++writes != nth) return;
  out.write(content.data(), static_cast<std::streamsize>(content.size() / 2));
  out.flush();
  std::raise(SIGKILL);
}

void write_file_atomic(const std::string& path, const std::string& content) {
  write_atomic_with(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    check(out.good(), "cannot write {}: {}", tmp, std::strerror(errno));
    maybe_die_writing(path, out, content);
    out << content;
    out.flush();
    check(out.good(), "cannot write {}: {} (the previous version, if any, is kept)", path,
          errno != 0 ? std::strerror(errno) : "write failed");
  });
}

std::string read_file(const std::string& path) {
  check(!fs::is_directory(path), "cannot read {}: it is a directory, not a file", path);
  std::ifstream in(path, std::ios::binary);
  check(in.good(), "cannot read {}: {}", path, fs::exists(path) ? "permission denied" : "no such file");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

bool file_exists(const std::string& path) {
  return fs::exists(path);
}

void ensure_writable_directory(const std::string& path) {
  std::error_code ec;
  fs::create_directories(path, ec);
  check(!ec, "cannot create directory {}: {}", path, ec.message());
  check(fs::is_directory(path), "{} exists and is not a directory", path);
  check(::access(path.c_str(), W_OK) == 0, "directory {} is not writable", path);
}

}  // namespace hlt
