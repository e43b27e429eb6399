// Crash safety of a result with its trend points: a server killed while
// finish_job stores them leaves each analysis job done with its result and
// every point, or still running with neither.
#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <string>

#include "ambdiag/storage/historian.h"
#include "crash_child.h"
#include "historian_fixture.h"
#include "sqlite_raw.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

// A series whose name is longer than a page, so a guard page can sit in it.
const std::string kLongName = "mode." + std::string(3 * 4096, 'x') + ".f_hz";

std::vector<SeriesValue> values_of(std::int64_t job_id) {
  return {{"detection.ratio", "1", 0.01 * static_cast<double>(job_id), std::nullopt},
          {"fit.nrmse", "1", 0.02, std::nullopt},
          {kLongName, "Hz", 50.0 + 0.001 * static_cast<double>(job_id), 0.1}};
}

std::string run_of(int i) { return "P-1/r" + std::to_string(i); }

void add_runs_and_jobs(const std::string& path, int n) {
  auto h = Historian::open(path);
  for (int i = 0; i < n; ++i) {
    auto j = nlohmann::json::parse(ambdiag::testing::run_json_text(run_of(i), 1, "P-1"));
    j["started_at"] = utc_from_ns(ns_from_utc("2026-01-01T00:00:00Z", "t0") + i * 3'600'000'000'000LL);
    h.begin_run(run_header_from_json(j.dump()));
    h.enqueue_job({"analysis", "P-1", run_of(i), 1, 0});
  }
}

// Each job: done with its result and its run's three points, or not done
// with neither. Returns how many are done.
int check_results_and_points_together(Historian& h) {
  int done = 0;
  for (const auto& j : h.list_jobs({})) {
    const auto ratio = h.run_points("P-1", "detection.ratio", {j.key.run_id});
    const auto mode = h.run_points("P-1", kLongName, {j.key.run_id});
    if (j.status == JobStatus::done) {
      ++done;
      EXPECT_EQ(j.result_json, "{}");
      EXPECT_EQ(ratio.size(), 1u) << "job " << j.job_id;
      if (!ratio.empty()) {
        EXPECT_DOUBLE_EQ(ratio[0].value, 0.01 * static_cast<double>(j.job_id));
      }
      EXPECT_EQ(mode.size(), 1u) << "job " << j.job_id;
    } else {
      EXPECT_FALSE(j.result_json) << "job " << j.job_id;
      EXPECT_TRUE(ratio.empty() && mode.empty()) << "job " << j.job_id << " has points without its result";
    }
  }
  return done;
}

TEST(HistorianTrendsCrash, KilledWhileThePointsAreWrittenLeavesNeitherResultNorPoints) {
  const std::string path = (ambdiag::testing::scratch_dir() / "h.db").string();
  constexpr int kJobs = 12, kFinished = 5;
  add_runs_and_jobs(path, kJobs);
  const auto child = crash::fork_child([&](int fd) {
    auto h = Historian::open(path);
    for (int i = 0; i < kFinished; ++i) {
      const auto j = h.claim_job("child");
      h.finish_job(j->job_id, j->attempts, "{}", {}, values_of(j->job_id));
    }
    // The next finish faults inside the long series name, after the result
    // and the first points went into the transaction.
    const auto j = h.claim_job("child");
    auto values = values_of(j->job_id);
    std::string& name = values.back().name;
    const auto page = static_cast<std::uintptr_t>(::sysconf(_SC_PAGESIZE));
    const auto mid = (reinterpret_cast<std::uintptr_t>(name.data()) + name.size() / 2) & ~(page - 1);
    crash::report_guard_page_faults(fd);
    ::mprotect(reinterpret_cast<void*>(mid), page, PROT_NONE);
    h.finish_job(j->job_id, j->attempts, "{}", {}, values);
  });
  ASSERT_GE(child.pid, 0);
  const crash::Killed k = crash::kill_after_report(child.pid, child.fd);
  EXPECT_TRUE(k.reported && k.by_sigkill());
  EXPECT_EQ(k.byte, 'T');
  auto h = Historian::open(path);
  EXPECT_EQ(raw_integrity_check(path), "ok");
  EXPECT_EQ(check_results_and_points_together(h), kFinished);
  EXPECT_EQ(h.count_jobs(JobStatus::running), 1);
}

TEST(HistorianTrendsCrash, KilledAtAnyTimeInALoopOfFinishesResultsAndPointsGoTogether) {
  const std::string path = (ambdiag::testing::scratch_dir() / "h.db").string();
  constexpr int kJobs = 400;
  add_runs_and_jobs(path, kJobs);
  int total_done = 0;
  for (int round = 0; round < 3; ++round) {
    // Into the loop, at a moment that differs.
    const auto k = crash::kill_a_finishing_loop(path, static_cast<useconds_t>(300 + 900 * round), [](Historian& h, const Job& j) {
      h.finish_job(j.job_id, j.attempts, "{}", {}, values_of(j.job_id));
    });
    ASSERT_TRUE(k.reported);
    ASSERT_TRUE(k.by_sigkill()) << "the child finished all jobs before it was killed";
    auto h = Historian::open(path);
    EXPECT_EQ(raw_integrity_check(path), "ok");
    const int done = check_results_and_points_together(h);
    EXPECT_GE(done, total_done + 20);
    total_done = done;
  }
}

}  // namespace
}  // namespace ambdiag::storage
