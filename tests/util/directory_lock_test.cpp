#include "hlt/util/directory_lock.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "hlt/util/error.h"
#include "hlt/util/files.h"

namespace hlt {
namespace {
namespace fs = std::filesystem;

TEST(DirectoryLock, SecondHolderIsRefusedWithTheFirstOnesPid) {
  const fs::path dir = fs::temp_directory_path() / "hlt_lock_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  {
    DirectoryLock first(dir.string());
    EXPECT_EQ(read_file((dir / DirectoryLock::kFile).string()), std::to_string(::getpid()));
    try {
      DirectoryLock second(dir.string());
      ADD_FAILURE() << "a second lock was granted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("in use by process " + std::to_string(::getpid())),
                std::string::npos)
          << e.what();
    }
  }
  // Released with its holder.
  DirectoryLock again(dir.string());
}

TEST(DirectoryLock, StaleTemporariesAreRemovedAndNothingElse) {
  const fs::path dir = fs::temp_directory_path() / "hlt_stale_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  write_file_atomic((dir / "checkpoint.pt").string(), "keep");
  write_file_atomic((dir / "checkpoint.pt.tmp.1234").string(), "stale");
  remove_stale_temporaries(dir.string());
  EXPECT_TRUE(fs::exists(dir / "checkpoint.pt"));
  EXPECT_FALSE(fs::exists(dir / "checkpoint.pt.tmp.1234"));
}

}  // namespace
}  // namespace hlt
