// A child process killed by its parent at a chosen moment inside SQLite
// (crash_test.cc, jobs_crash_test.cc): the child makes a page of the data it
// hands SQLite unreadable; when SQLite reads it, the SIGSEGV handler reports
// 'T' on a pipe and waits for the parent's SIGKILL.
#pragma once

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

namespace ambdiag::storage::crash {

inline int g_report_fd = -1;

inline void on_guard_page(int) {
  const char c = 'T';
  [[maybe_unused]] auto n = ::write(g_report_fd, &c, 1);
  for (;;) ::pause();
}

// In the child, before the call that reads the guarded page: a fault is
// reported on `fd`.
inline void report_guard_page_faults(int fd) {
  g_report_fd = fd;
  struct sigaction sa {};
  sa.sa_handler = on_guard_page;
  ::sigaction(SIGSEGV, &sa, nullptr);
}

// In the parent: what became of a child killed after its report.
struct Killed {
  bool reported = false;  // a byte arrived before the child ended
  char byte = 0;
  int status = 0;         // from waitpid
  bool by_sigkill() const { return WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL; }
};

// Waits for the child's report byte on `fd`, kills the child, reaps it and
// closes `fd`.
inline Killed kill_after_report(pid_t child, int fd) {
  Killed k;
  k.reported = ::read(fd, &k.byte, 1) == 1;
  ::kill(child, SIGKILL);
  ::waitpid(child, &k.status, 0);
  ::close(fd);
  return k;
}

}  // namespace ambdiag::storage::crash
