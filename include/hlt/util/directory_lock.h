// hlt::DirectoryLock: an exclusive lock on a directory (an flock()ed `.lock` file in it holding the holder's
// pid), taken by whichever process writes the directory, so that a second writer is refused instead of
// truncating a live run's files. The kernel releases it when the holder exits, however it exits.
#pragma once

#include <string>

namespace hlt {

class DirectoryLock {
 public:
  // Throws hlt::Error naming the holder's pid if another process holds the lock.
  explicit DirectoryLock(const std::string& dir);
  ~DirectoryLock();
  DirectoryLock(const DirectoryLock&) = delete;
  DirectoryLock& operator=(const DirectoryLock&) = delete;

  static constexpr const char* kFile = ".lock";

 private:
  int fd_ = -1;
};

// Removes the temporary files that interrupted atomic writes (write_file_atomic) left in `dir`. Only safe
// while holding the directory's lock.
void remove_stale_temporaries(const std::string& dir);

}  // namespace hlt
