// Real child processes for the integration tests: start with arguments and
// environment, stderr to a file, signal, wait with a deadline.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <map>
#include <string>
#include <vector>

namespace ambdiag::testing {

class Process {
 public:
  // Starts `argv[0]` with `argv`; stdout and stderr go to `log_path`.
  Process(std::vector<std::string> argv, const std::map<std::string, std::string>& env, const std::string& log_path);
  ~Process();  // kills (SIGKILL) and reaps a child still running
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  void signal(int sig);
  // Exit code, or -signal if killed; -1000 if still running at the deadline
  // (stretched ten-fold in an AddressSanitizer build).
  int wait(std::chrono::milliseconds timeout);
  bool running();
  std::string log() const;
  pid_t pid() const { return pid_; }

 private:
  pid_t pid_ = -1;
  int status_ = 0;
  bool reaped_ = false;
  std::string log_path_;
};

}  // namespace ambdiag::testing
