// An exclusive advisory lock (flock) held by one process on a lock file,
// with the holder's pid written into it so that a refused process can name
// it. The kernel frees the lock when the holder exits, kill -9 included.
// Used for one agent per spool folder and one server per historian file.
#pragma once

#include <string>

namespace ambdiag {

class ProcessLock {
 public:
  // Creates the file if missing. Throws InputError "<what> is in use by
  // another <holder> (pid N)<advice>" when another process holds the lock,
  // std::runtime_error when the file cannot be opened or locked.
  ProcessLock(const std::string& path, const std::string& what, const std::string& holder, const std::string& advice);
  ~ProcessLock();
  ProcessLock(const ProcessLock&) = delete;
  ProcessLock& operator=(const ProcessLock&) = delete;

 private:
  int fd_ = -1;
};

}  // namespace ambdiag
