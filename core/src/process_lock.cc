#include "ambdiag/core/process_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "ambdiag/core/error.h"

namespace ambdiag {

ProcessLock::ProcessLock(const std::string& path, const std::string& what, const std::string& holder,
                         const std::string& advice) {
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) throw std::runtime_error(path + ": cannot open the lock file (" + std::strerror(errno) + ")");
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    char pid_text[32] = {};
    const ssize_t n = ::pread(fd_, pid_text, sizeof pid_text - 1, 0);
    ::close(fd_);
    fd_ = -1;
    if (err != EWOULDBLOCK) throw std::runtime_error(path + ": cannot lock (" + std::strerror(err) + ")");
    std::string pid(pid_text, n > 0 ? static_cast<size_t>(n) : 0);
    pid.erase(pid.find_last_not_of(" \n") + 1);
    throw InputError(what + " is in use by another " + holder + (pid.empty() ? std::string() : " (pid " + pid + ")") + advice);
  }
  const std::string me = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd_, 0) == 0) (void)!::pwrite(fd_, me.data(), me.size(), 0);
}

ProcessLock::~ProcessLock() {
  if (fd_ >= 0) ::close(fd_);  // closing the descriptor releases the lock
}

}  // namespace ambdiag
