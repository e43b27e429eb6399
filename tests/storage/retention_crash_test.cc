// Crash safety of the retention sweep: a sweep killed at any moment leaves
// each run with all its samples, byte for byte, or marked dropped (the bytes
// it deleted and the chunks left adding up to what it had); the next sweep
// finishes what the dead one began.
#include <gtest/gtest.h>
#include <unistd.h>

#include <string>
#include <vector>

#include "ambdiag/storage/historian.h"
#include "crash_child.h"
#include "retention_fixture.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

constexpr const char* kHolder = "crash-test";  // the same in the child and here: no waiting for its lease

SweepOptions small_batches() {
  SweepOptions opt;
  opt.holder = kHolder;
  opt.max_bytes_per_transaction = 20000;  // 2 or 3 chunks of 8000 bytes
  opt.yield_between_transactions = false;
  return opt;
}

// Runs of 8 chunks, all received long ago.
std::vector<StoredRun> store_old_runs(const std::string& path, int n) {
  auto h = Historian::open(path);
  std::vector<StoredRun> runs;
  for (int i = 0; i < n; ++i) {
    runs.push_back(store_run(h, "P-7/r" + std::to_string(100 + i), "P-7", 8000, static_cast<unsigned>(i), 1000));
    received_days_ago(path, runs.back().run_id, 100);
  }
  return runs;
}

// Each run has all its samples or is marked dropped with its chunks a
// suffix of what it had; returns how many are marked.
int check_each_run_whole_or_marked(Historian& h, const std::string& path, const std::vector<StoredRun>& runs) {
  int marked = 0;
  for (const auto& run : runs) {
    const auto info = h.find_run(run.run_id);
    const std::int64_t chunks = chunks_held(path, run.run_id);
    if (!info->samples_dropped_at) {
      EXPECT_EQ(chunks, 8) << run.run_id;
      EXPECT_EQ(h.read_samples(run.run_id), ambdiag::testing::as_string(run.bytes)) << run.run_id;
      EXPECT_EQ(info->samples_dropped_bytes, 0) << run.run_id;
      continue;
    }
    ++marked;
    EXPECT_EQ(info->samples_dropped_bytes + chunks * 8000, static_cast<std::int64_t>(run.bytes.size())) << run.run_id;
    const std::string where = "run_id = '" + run.run_id + "'";
    if (chunks > 0) {  // what is left is the end of the run
      EXPECT_EQ(raw_query_int(path, ("SELECT min(seq) FROM sample_chunks WHERE " + where).c_str()), 8 - chunks) << run.run_id;
    }
    EXPECT_EQ(raw_query_int(path, ("SELECT samples_state = 'dropped' FROM runs WHERE " + where).c_str()), chunks == 0 ? 1 : 0);
  }
  return marked;
}

TEST(RetentionCrash, KilledBetweenTheTransactionsOfARunTheRunReadsDroppedAndTheNextSweepFinishesIt) {
  const std::string path = (ambdiag::testing::scratch_dir() / "h.db").string();
  const auto runs = store_old_runs(path, 3);
  const crash::Child child = crash::fork_child([&](int fd) {
    auto h = Historian::open(path);
    SweepOptions opt = small_batches();
    opt.after_commit = [fd] {  // after the first transaction: marked, 2 chunks gone
      crash::report(fd);
      for (;;) ::pause();
    };
    h.sweep_retention(samples_for_days(30), opt);
  });
  ASSERT_GE(child.pid, 0);
  const crash::Killed k = crash::kill_after_report(child.pid, child.fd);
  ASSERT_TRUE(k.reported && k.by_sigkill());
  EXPECT_EQ(raw_integrity_check(path), "ok");
  auto h = Historian::open(path);
  EXPECT_EQ(check_each_run_whole_or_marked(h, path, runs), 1);
  EXPECT_EQ(chunks_held(path, runs[0].run_id), 6);
  EXPECT_NE(h.find_run(runs[0].run_id)->samples_dropped_at, std::nullopt);

  const auto r = h.sweep_retention(samples_for_days(30), small_batches());
  ASSERT_EQ(r.runs.size(), 3u);
  EXPECT_EQ(r.runs[0].run_id, runs[0].run_id);
  EXPECT_EQ(r.runs[0].reason, "interrupted");
  EXPECT_EQ(r.runs[0].bytes, 6 * 8000);
  EXPECT_EQ(check_each_run_whole_or_marked(h, path, runs), 3);
  EXPECT_EQ(raw_query_int(path, "SELECT count(*) FROM sample_chunks"), 0);
}

TEST(RetentionCrash, KilledAtAnyMomentEveryRunIsWholeOrMarkedDropped) {
  const std::string path = (ambdiag::testing::scratch_dir() / "h.db").string();
  const auto runs = store_old_runs(path, 60);
  int marked_before = 0;
  for (int round = 0; round < 3; ++round) {
    // Killed the moment after its 5th, 20th or 40th transaction: wherever
    // it is then (a run's drop is 3 transactions), the sweep goes on until
    // the signal lands.
    const crash::Child child = crash::fork_child([&](int fd) {
      auto h = Historian::open(path);
      SweepOptions opt = small_batches();
      int commits = 0;
      opt.after_commit = [&, fd] {
        if (++commits == (round == 0 ? 5 : 20 * round)) crash::report(fd);
      };
      h.sweep_retention(samples_for_days(30), opt);
    });
    ASSERT_GE(child.pid, 0);
    const crash::Killed k = crash::kill_after_report(child.pid, child.fd);
    ASSERT_TRUE(k.reported);
    ASSERT_TRUE(k.by_sigkill()) << "the sweep ended before it was killed";
    EXPECT_EQ(raw_integrity_check(path), "ok");
    auto h = Historian::open(path);
    const int marked = check_each_run_whole_or_marked(h, path, runs);
    EXPECT_GT(marked, marked_before) << "round " << round << ": the sweep got nowhere";
    EXPECT_LT(marked, 60) << "round " << round;
    marked_before = marked;
  }
  auto h = Historian::open(path);
  h.sweep_retention(samples_for_days(30), small_batches());
  EXPECT_EQ(check_each_run_whole_or_marked(h, path, runs), 60);
  EXPECT_EQ(raw_query_int(path, "SELECT count(*) FROM sample_chunks"), 0);
  EXPECT_EQ(raw_query_int(path, "SELECT sum(samples_dropped_bytes) FROM runs"), 60 * 64000);
}

}  // namespace
}  // namespace ambdiag::storage
