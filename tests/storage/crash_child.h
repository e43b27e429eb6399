// A child process killed by its parent at a chosen moment inside SQLite
// (crash_test.cc, jobs_crash_test.cc, trends_crash_test.cc): the child makes
// a page of the data it hands SQLite unreadable; when SQLite reads it, the
// SIGSEGV handler reports 'T' on a pipe and waits for the parent's SIGKILL.
// Or a child in a loop of writes, killed a moment after it reports.
#pragma once

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <string>

#include "ambdiag/storage/historian.h"

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

// Waits for the child's report byte on `fd`, lets it go on for `delay_us`,
// kills the child, reaps it and closes `fd`.
inline Killed kill_after_report(pid_t child, int fd, useconds_t delay_us = 0) {
  Killed k;
  k.reported = ::read(fd, &k.byte, 1) == 1;
  if (delay_us > 0) ::usleep(delay_us);
  ::kill(child, SIGKILL);
  ::waitpid(child, &k.status, 0);
  ::close(fd);
  return k;
}

// A forked child that runs `body(report_fd)` (and exits 3 should it
// return); the parent gets its pid (-1 when fork or pipe failed) and the
// read end of its report pipe.
struct Child {
  pid_t pid = -1;
  int fd = -1;
};
template <class F>
Child fork_child(F&& body) {
  int fds[2];
  if (::pipe(fds) != 0) return {};
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    body(fds[1]);
    ::_exit(3);
  }
  ::close(fds[1]);
  return {pid, fds[0]};
}

// In the child: reports 'F' on `fd` (e.g. once it is well into a loop).
inline void report(int fd) {
  const char c = 'F';
  [[maybe_unused]] auto n = ::write(fd, &c, 1);
}

// A server killed in its job loop: a child opens the file, queues again what
// a killed predecessor left running, and runs `finish(historian, job)` for
// every job it claims; it is killed `delay_us` after its 20th.
template <class Finish>
Killed kill_a_finishing_loop(const std::string& path, useconds_t delay_us, Finish&& finish) {
  const Child child = fork_child([&](int fd) {
    auto h = Historian::open(path);
    h.requeue_running_jobs();
    int n = 0;
    while (auto j = h.claim_job("child")) {
      finish(h, *j);
      if (++n == 20) report(fd);
    }
  });
  if (child.pid < 0) return {};
  return kill_after_report(child.pid, child.fd, delay_us);
}

}  // namespace ambdiag::storage::crash
