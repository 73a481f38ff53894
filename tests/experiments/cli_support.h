// Helpers of the end-to-end tests that run hlt_train and hlt_rollout as subprocesses.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "hlt/util/scalar_logger.h"
#include "support/subprocess.h"

namespace hlt {
namespace test {

inline std::string fresh_dir(const std::string& name) {
  const std::filesystem::path p = std::filesystem::temp_directory_path() / "hlt_cli_test" / name;
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p.parent_path());
  return p.string();
}

// Rows of a log without wall-clock values: what must be identical between two runs of the same seed.
inline std::vector<std::string> comparable_rows(const std::string& path) {
  std::vector<std::string> rows;
  for (const auto& r : ScalarLogger::read(path)) {
    if (r.tag.rfind("time/", 0) == 0) continue;
    rows.push_back(fmt::format("{},{},{:.17g}", r.step, r.tag, r.value));
  }
  return rows;
}

}  // namespace test
}  // namespace hlt
