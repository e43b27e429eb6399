// Crash safety of finish_job: a server killed while it stores a result
// leaves each job done with all its files, or still running with none.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdint>
#include <string>

#include "ambdiag/storage/historian.h"
#include "crash_child.h"
#include "sqlite_raw.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

std::string result_of(std::int64_t id) { return R"({"job": )" + std::to_string(id) + "}"; }

// The job's files: a small one, then 1 MiB that names the job in every byte.
std::vector<JobArtifact> files_of(std::int64_t id) {
  return {{"a.csv", "text/csv", "job," + std::to_string(id) + "\n"},
          {"b.bin", "application/octet-stream", std::string(1 << 20, static_cast<char>('A' + id % 26))}};
}

void enqueue_jobs(const std::string& path, int n) {
  auto h = Historian::open(path);
  for (int i = 0; i < n; ++i) h.enqueue_job({"analysis", "P-1", "r" + std::to_string(i), 1, 0});
}

// Every job is done with exactly its result and files, or running/queued
// with no result and no file. Returns how many are done.
int check_each_job_all_or_nothing(Historian& h) {
  int done = 0;
  for (const auto& j : h.list_jobs({})) {
    if (j.status == JobStatus::done) {
      ++done;
      EXPECT_EQ(j.result_json, result_of(j.job_id));
      const auto files = files_of(j.job_id);
      EXPECT_EQ(h.list_artifacts(j.job_id).size(), files.size()) << "job " << j.job_id;
      for (const auto& f : files) {
        const auto a = h.find_artifact(j.job_id, f.name);
        EXPECT_TRUE(a && a->data == f.data) << "job " << j.job_id << " " << f.name;
      }
    } else {
      EXPECT_TRUE(j.status == JobStatus::running || j.status == JobStatus::queued) << "job " << j.job_id;
      EXPECT_FALSE(j.result_json) << "job " << j.job_id;
      EXPECT_TRUE(h.list_artifacts(j.job_id).empty()) << "job " << j.job_id;
    }
  }
  return done;
}

// Waits for the child's report byte, kills it, returns the byte.
char kill_child_after_report(pid_t child, int fd) {
  const crash::Killed k = crash::kill_after_report(child, fd);
  EXPECT_TRUE(k.reported) << "the child ended before it reported";
  EXPECT_TRUE(k.by_sigkill());
  return k.byte;
}

TEST(HistorianJobsCrash, KilledInsideFinishJobLeavesTheJobRunningWithoutResultOrFiles) {
  const std::string path = (ambdiag::testing::scratch_dir() / "h.db").string();
  constexpr int kJobs = 30, kFinished = 10;
  enqueue_jobs(path, kJobs);

  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(fds[0]);
    auto h = Historian::open(path);
    for (int i = 0; i < kFinished; ++i) {
      const auto j = h.claim_job("child");
      h.finish_job(j->job_id, j->attempts, result_of(j->job_id), files_of(j->job_id));
    }
    // The next finish: the second file's bytes fault half way through, after
    // the status update and the first file went into the transaction.
    const auto j = h.claim_job("child");
    auto files = files_of(j->job_id);
    const auto page = static_cast<std::uintptr_t>(::sysconf(_SC_PAGESIZE));
    const auto mid = (reinterpret_cast<std::uintptr_t>(files[1].data.data()) + files[1].data.size() / 2) & ~(page - 1);
    crash::report_guard_page_faults(fds[1]);
    ::mprotect(reinterpret_cast<void*>(mid), page, PROT_NONE);
    h.finish_job(j->job_id, j->attempts, result_of(j->job_id), files);
    ::_exit(3);  // not reached
  }
  ::close(fds[1]);
  EXPECT_EQ(kill_child_after_report(child, fds[0]), 'T');

  auto h = Historian::open(path);
  EXPECT_EQ(raw_integrity_check(path), "ok");
  EXPECT_EQ(check_each_job_all_or_nothing(h), kFinished);
  JobFilter running;
  running.status = JobStatus::running;
  const auto cut = h.list_jobs(running);
  ASSERT_EQ(cut.size(), 1u);
  EXPECT_EQ(cut[0].attempts, 1);
  EXPECT_EQ(h.count_jobs(JobStatus::queued), kJobs - kFinished - 1);

  // The restarted server requeues it; the next attempt completes it.
  EXPECT_EQ(h.requeue_running_jobs(), 1);
  const auto again = h.claim_job("restarted");
  ASSERT_TRUE(again);
  EXPECT_EQ(again->job_id, cut[0].job_id);
  EXPECT_EQ(again->attempts, 2);
  EXPECT_FALSE(h.finish_job(again->job_id, 1, result_of(again->job_id), files_of(again->job_id)));
  EXPECT_TRUE(h.finish_job(again->job_id, 2, result_of(again->job_id), files_of(again->job_id)));
  EXPECT_EQ(check_each_job_all_or_nothing(h), kFinished + 1);
}

TEST(HistorianJobsCrash, KilledAtAnyTimeInALoopOfFinishesEveryJobIsAllOrNothing) {
  const std::string path = (ambdiag::testing::scratch_dir() / "h.db").string();
  constexpr int kJobs = 400;
  enqueue_jobs(path, kJobs);
  int total_done = 0;
  // Three servers in turn, each killed at another moment of its loop.
  for (int round = 0; round < 3; ++round) {
    // Into the loop, at a moment that differs.
    const auto k = crash::kill_a_finishing_loop(path, static_cast<useconds_t>(500 + 1700 * round), [](Historian& h, const Job& j) {
      h.finish_job(j.job_id, j.attempts, result_of(j.job_id), files_of(j.job_id));
    });
    ASSERT_TRUE(k.reported);
    ASSERT_TRUE(k.by_sigkill()) << "the child finished all jobs before it was killed";

    auto h = Historian::open(path);
    EXPECT_EQ(raw_integrity_check(path), "ok");
    const int done = check_each_job_all_or_nothing(h);
    EXPECT_GE(done, total_done + 20);
    EXPECT_LE(h.count_jobs(JobStatus::running), 1);
    total_done = done;
  }
}

}  // namespace
}  // namespace ambdiag::storage
