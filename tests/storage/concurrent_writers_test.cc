// Four connections writing the same things at once, on both backends: what
// each write method promises holds when it is not the only writer (SQLite
// serialises them with its write lock; PostgreSQL's writers run at once and
// rely on the locks and constraints in docs/storage.md "What guards each
// write").
#include <gtest/gtest.h>

#include <atomic>
#include <barrier>
#include <chrono>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"

namespace ambdiag::storage {
namespace {

using ambdiag::testing::checksum_of;
using ambdiag::testing::cut_chunks;
using ambdiag::testing::run_json_text;
using ambdiag::testing::samples_bytes;

using namespace std::chrono_literals;

constexpr int kWriters = 4;

class ConcurrentWritersTest : public ambdiag::testing::BackendTest {
 protected:
  // Runs `work(writer index, its own connection)` in kWriters threads that
  // start together.
  void in_parallel(const std::function<void(int, Historian&)>& work) {
    { auto h = Historian::open(location()); }  // the schema exists before they race
    std::atomic<int> ready{0};
    std::vector<std::thread> ts;
    for (int w = 0; w < kWriters; ++w)
      ts.emplace_back([&, w] {
        auto h = Historian::open(location());
        for (++ready; ready < kWriters;) std::this_thread::yield();
        try {
          work(w, h);
        } catch (const std::exception& e) {
          ADD_FAILURE() << "writer " << w << ": " << e.what();
        }
      });
    for (auto& t : ts) t.join();
  }
};
AMBDIAG_ON_BOTH_BACKENDS(ConcurrentWritersTest);

TEST_P(ConcurrentWritersTest, ModelVersionsPutAtOnceAreDistinctAndContiguous) {
  constexpr int kEach = 25;
  std::mutex mu;
  std::multiset<int> versions;
  in_parallel([&](int w, Historian& h) {
    for (int i = 0; i < kEach; ++i) {
      const int v = h.put_model("P-1", R"({"by": )" + std::to_string(w) + "}", "writer");
      std::lock_guard lock(mu);
      versions.insert(v);
    }
  });
  ASSERT_EQ(versions.size(), static_cast<size_t>(kWriters * kEach));
  int expected = 1;
  for (const int v : versions) EXPECT_EQ(v, expected++);  // 1..100, each once
  auto h = Historian::open(location(), Historian::Mode::read);
  EXPECT_EQ(h.list_models("P-1").size(), static_cast<size_t>(kWriters * kEach));
}

TEST_P(ConcurrentWritersTest, ClaimsAtOnceNeverHandAJobOutTwice) {
  constexpr int kJobs = 200;
  {
    auto h = Historian::open(location());
    auto batch = h.write_batch();
    for (int i = 0; i < kJobs; ++i) h.enqueue_job({"analysis", "P-1", "r" + std::to_string(i), 1, 0});
    batch.commit();
  }
  std::mutex mu;
  std::map<std::int64_t, int> times;
  std::vector<int> per_writer(kWriters, 0);
  in_parallel([&](int w, Historian& h) {
    while (auto j = h.claim_job("w" + std::to_string(w))) {
      {
        std::lock_guard lock(mu);
        ++times[j->job_id];
        ++per_writer[static_cast<size_t>(w)];
      }
      // The analysis, outside any transaction (SQLite's busy handler backs
      // off for milliseconds; without a pause one writer takes them all).
      std::this_thread::sleep_for(std::chrono::microseconds(500));
      EXPECT_TRUE(h.finish_job(j->job_id, j->attempts, "{}"));
    }
  });
  EXPECT_EQ(times.size(), static_cast<size_t>(kJobs));
  for (const auto& [id, n] : times) EXPECT_EQ(n, 1) << "job " << id;
  for (int w = 0; w < kWriters; ++w) EXPECT_GT(per_writer[static_cast<size_t>(w)], 0) << "writer " << w;
  auto h = Historian::open(location(), Historian::Mode::read);
  EXPECT_EQ(h.count_jobs(JobStatus::done), kJobs);
}

TEST_P(ConcurrentWritersTest, OneKeyEnqueuedAtOnceIsOneJob) {
  constexpr int kKeys = 50;
  std::mutex mu;
  std::map<std::int64_t, int> created;  // job id -> how many callers were told "created"
  std::set<std::int64_t> ids;
  in_parallel([&](int, Historian& h) {
    for (int k = 0; k < kKeys; ++k) {
      const auto [id, made] = h.enqueue_job({"analysis", "P-1", "r" + std::to_string(k), 1, 0});
      std::lock_guard lock(mu);
      ids.insert(id);
      created[id] += made;
    }
  });
  EXPECT_EQ(ids.size(), static_cast<size_t>(kKeys));
  for (const auto& [id, n] : created) EXPECT_EQ(n, 1) << "job " << id;
}

TEST_P(ConcurrentWritersTest, OneRunStreamedByFourWritersIsStoredOnceAndEndsComplete) {
  const auto header = run_header_from_json(run_json_text("P-1/a", 2, "P-1"));
  const auto bytes = samples_bytes(4000, 2, 3);
  const auto chunks = cut_chunks(bytes, 2, 100);
  std::atomic<std::int64_t> stored{0}, duplicates{0};
  in_parallel([&](int w, Historian& h) {
    h.begin_run(header);
    // Every writer sends every chunk, in its own order, then the end.
    for (size_t i = 0; i < chunks.size(); ++i) {
      const auto& c = chunks[(i * 7 + static_cast<size_t>(w) * 11) % chunks.size()];
      const auto r = h.put_chunks("P-1/a", std::span(&c, 1));
      stored += r.stored;
      duplicates += r.duplicates;
    }
    const auto end = h.end_run("P-1/a", 4000, checksum_of(bytes));
    EXPECT_EQ(end.status, RunStatus::complete) << end.reason;
  });
  EXPECT_EQ(stored, static_cast<std::int64_t>(chunks.size()));
  EXPECT_EQ(duplicates, static_cast<std::int64_t>(chunks.size()) * (kWriters - 1));
  auto h = Historian::open(location(), Historian::Mode::read);
  EXPECT_EQ(h.count_runs(), 1);
  const auto info = h.find_run("P-1/a");
  EXPECT_EQ(info->received_chunks, static_cast<std::int64_t>(chunks.size()));
  EXPECT_EQ(info->duplicate_chunks, static_cast<std::int64_t>(chunks.size()) * (kWriters - 1));
  EXPECT_EQ(h.read_samples("P-1/a"), ambdiag::testing::as_string(bytes));
}

// Lock order (docs/storage.md "Lock order"): an ingest batch that takes a
// run's lock, announces, then takes an analysed run's lock (an agent
// re-sending chunks of it), beside a finish_job of that run that announces
// job.done. Before the events' lock was taken last (at the batch's commit),
// the two took the run's lock and the events' in opposite orders and
// PostgreSQL broke the deadlock by failing one (SQLSTATE 40P01).
TEST_P(ConcurrentWritersTest, IngestBatchesAndFinishedJobsOfOneRunNeverDeadlock) {
  constexpr int kRounds = 8;
  const auto bytes = samples_bytes(400, 2, 5);
  const auto chunks = cut_chunks(bytes, 2, 100);
  const auto stored_run = [&](Historian& h, const std::string& id) {
    h.begin_run(run_header_from_json(run_json_text(id, 2, "P-1")));
    h.put_chunks(id, chunks);
    ASSERT_EQ(h.end_run(id, 400, checksum_of(bytes)).status, RunStatus::complete);
  };
  {
    auto h = Historian::open(location());
    for (const char* id : {"P-1/analysed", "P-1/w0", "P-1/w1"}) stored_run(h, id);
  }
  std::barrier round(kWriters);
  std::atomic<int> events{0};
  in_parallel([&](int w, Historian& h) {
    for (int i = 0; i < kRounds; ++i) {
      if (w < 2) {  // the ingest: its own run, then the analysed one re-sent
        round.arrive_and_wait();
        auto batch = h.write_batch();
        const std::string own = "P-1/w" + std::to_string(w);
        h.put_chunks(own, std::span(&chunks[0], 1));
        h.append_event("run.status", "P-1", "{}");
        std::this_thread::sleep_for(5ms);  // the finisher takes the analysed run meanwhile
        h.put_chunks("P-1/analysed", std::span(&chunks[1], 1));
        h.append_event("run.status", "P-1", "{}");
        batch.commit();
        events += 2;
      } else {  // an analysis worker storing a result of the analysed run
        const int version = 100 * w + i;
        h.enqueue_job({"analysis", "P-1", "P-1/analysed", version, 0});
        round.arrive_and_wait();
        const auto job = h.claim_job("w" + std::to_string(w), {"analysis"});
        if (!job) continue;  // the other finisher took both
        auto batch = h.write_batch();
        ASSERT_TRUE(h.finish_job(job->job_id, job->attempts, "{}", {}, std::vector<SeriesValue>{{"x", "1", 1.0, {}}}));
        std::this_thread::sleep_for(5ms);
        h.append_event("job.done", "P-1", "{}");
        batch.commit();
        events += 1;
      }
    }
  });
  auto h = Historian::open(location(), Historian::Mode::read);
  EXPECT_EQ(static_cast<int>(h.events_after(0, 1000).size()), events.load());
  EXPECT_GE(events.load(), 2 * 2 * kRounds);
}

// A TransientError is a whole transaction to run again: two batches that
// take two runs' locks in opposite orders deadlock on PostgreSQL, which
// fails one; retry_transient runs it again and both end stored once (the
// rolled-back attempt's counters are not kept). SQLite: no deadlock, each
// batch runs once.
TEST_P(ConcurrentWritersTest, ABatchFailedByADeadlockIsStoredOnceWhenRunAgain) {
  const auto bytes = samples_bytes(800, 2, 9);
  const auto chunks = cut_chunks(bytes, 2, 100);
  {
    auto h = Historian::open(location());
    for (const char* id : {"P-1/x", "P-1/y"}) h.begin_run(run_header_from_json(run_json_text(id, 2, "P-1")));
  }
  std::barrier start(2);
  std::atomic<int> attempts{0}, transient{0};
  std::atomic<int> ran{0};
  in_parallel([&](int w, Historian& h) {
    if (w >= 2) return;
    const std::string first = w == 0 ? "P-1/x" : "P-1/y", second = w == 0 ? "P-1/y" : "P-1/x";
    bool waited = false;
    storage::retry_transient([&] {
      ++attempts;
      auto batch = h.write_batch();
      try {
        for (std::size_t k = static_cast<std::size_t>(w); k < chunks.size(); k += 2) {
          h.put_chunks(first, std::span(&chunks[k], 1));
          if (!waited && postgres()) {  // the first attempts meet with a lock each (SQLite: one writer at a time)
            waited = true;
            start.arrive_and_wait();
            std::this_thread::sleep_for(20ms);
          }
          h.put_chunks(second, std::span(&chunks[k], 1));
        }
      } catch (const TransientError&) {
        ++transient;
        throw;
      }
      batch.commit();
    });
    ++ran;
  });
  EXPECT_EQ(ran, 2);
  if (postgres())
    EXPECT_GE(transient, 1) << "no deadlock: the test did not test the retry";
  else
    EXPECT_EQ(transient, 0);
  EXPECT_EQ(attempts, 2 + transient);
  auto h = Historian::open(location());
  for (const char* id : {"P-1/x", "P-1/y"}) {
    const auto info = h.find_run(id);
    EXPECT_EQ(info->received_chunks, static_cast<std::int64_t>(chunks.size())) << id;
    EXPECT_EQ(info->duplicate_chunks, 0) << id;
    EXPECT_EQ(h.end_run(id, 800, checksum_of(bytes)).status, RunStatus::complete) << id;
  }
}

TEST_P(ConcurrentWritersTest, ATokenNameAddedAtOnceIsGivenOnce) {
  std::atomic<int> given{0}, refused{0};
  in_parallel([&](int, Historian& h) {
    try {
      h.add_token("ops", Role::operator_);
      ++given;
    } catch (const InputError&) {
      ++refused;
    }
  });
  EXPECT_EQ(given, 1);
  EXPECT_EQ(refused, kWriters - 1);
}

AlarmChanges raise_change(const std::string& pump, const std::string& rule) {
  AlarmChanges c;
  c.pump_id = pump;
  c.alarms.push_back(ambdiag::testing::open_alarm(pump, rule));
  c.events.emplace_back(0, ambdiag::testing::alarm_event("raise", "normal", "unack_active"));
  return c;
}

TEST_P(ConcurrentWritersTest, OneAlarmOfARuleRaisedAtOnceIsOpenOnce) {
  std::atomic<int> raised{0}, refused{0};
  in_parallel([&](int, Historian& h) {
    auto c = raise_change("P-1", "detection");
    try {
      h.apply_alarm_changes(c);
      ++raised;
    } catch (const InputError&) {
      ++refused;
    }
  });
  EXPECT_EQ(raised, 1);
  EXPECT_EQ(refused, kWriters - 1);
}

// A plant system polls the journal "after the last seq I saw": it must see
// every entry, so seqs must become visible in their order.
TEST_P(ConcurrentWritersTest, APollerOfTheAlarmJournalMissesNoEntry) {
  constexpr int kEach = 30;
  std::atomic<bool> done{false};
  std::set<std::int64_t> polled;
  std::thread poller([&] {
    auto r = Historian::open(location());
    std::int64_t after = 0;
    for (bool last = false; !last;) {
      last = done.load();  // one more poll after the writers ended
      for (const auto& e : r.alarm_events(after, 1000)) {
        polled.insert(e.seq);
        after = e.seq;
      }
    }
  });
  in_parallel([&](int w, Historian& h) {
    for (int i = 0; i < kEach; ++i) {
      auto c = raise_change("P-" + std::to_string(w) + "-" + std::to_string(i), "detection");
      h.apply_alarm_changes(c);
    }
  });
  done = true;
  poller.join();
  auto h = Historian::open(location(), Historian::Mode::read);
  const auto all = h.alarm_events(0, 1000);
  ASSERT_EQ(all.size(), static_cast<size_t>(kWriters * kEach));
  for (const auto& e : all) EXPECT_TRUE(polled.count(e.seq)) << "the poller missed seq " << e.seq;
}

}  // namespace
}  // namespace ambdiag::storage
