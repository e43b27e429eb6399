// A child process killed by its parent at a chosen moment inside SQLite
// (crash_test.cc, jobs_crash_test.cc): the child makes a page of the data it
// hands SQLite unreadable; when SQLite reads it, the SIGSEGV handler reports
// 'T' on a pipe and waits for the parent's SIGKILL.
#pragma once

#include <signal.h>
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

}  // namespace ambdiag::storage::crash
