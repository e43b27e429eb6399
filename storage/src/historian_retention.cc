// Historian: retention (schema v9; retention.h, docs/storage.md
// "Retention"). Each pump's policy is versioned like its models; the sweep
// plans from reads, then drops run by run, each drop a write transaction
// that re-checks its run (still held, not receiving, not needed) so that it
// is idempotent beside ingest, jobs and another sweep. A run's samples go in
// transactions of at most max_bytes_per_transaction: the first marks the run
// `dropping` (from then on it reads as dropped), the last `dropped`; a drop a
// crash interrupted is finished by the next sweep. On PostgreSQL a day
// partition of sample_chunks goes whole first (drop_partitions), in one
// transaction with its runs' marks, once its kept runs (at most a quarter
// of its bytes) are moved to sample_chunks_kept (schema v10).
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <map>
#include <set>
#include <thread>

#include <nlohmann/json.hpp>

#include "ambdiag/storage/historian.h"
#include "historian_impl.h"

namespace ambdiag::storage {

namespace {

using SteadyClock = std::chrono::steady_clock;
using SystemClock = std::chrono::system_clock;

// The run R (an SQL expression) is needed: a reference version, an alarm
// that is not normal or a queued or running job names it. Never dropped.
#define AMBDIAG_RUN_NEEDED(R)                                                                          \
  "(EXISTS (SELECT 1 FROM reference_runs x WHERE x.run_id = " R                                        \
  ") OR EXISTS (SELECT 1 FROM alarms a WHERE a.run_id = " R " AND a.state <> 'normal') OR EXISTS ("     \
  "SELECT 1 FROM jobs j WHERE j.run_id = " R " AND j.status IN ('queued', 'running')))"

// pid@host#n: unique per sweep, also between two sweeps of one process.
std::string default_holder() {
  static std::atomic<int> n{0};
  char host[256] = {};
  ::gethostname(host, sizeof host - 1);
  return std::to_string(::getpid()) + "@" + host + "#" + std::to_string(++n);
}

SystemClock::time_point days_before(SystemClock::time_point now, double days) {
  return now - std::chrono::duration_cast<SystemClock::duration>(std::chrono::duration<double, std::ratio<86400>>(days));
}

RetentionVersion read_version(const Stmt& s, const std::string& pump_id) {
  return {pump_id, static_cast<int>(s.col_int(0)), s.col_text(1), s.col_text(2), s.col_text(3)};
}

class Sweep {
 public:
  Sweep(Historian::Impl& impl, const SweepOptions& opt, SweepReport& r)
      : impl_(impl), opt_(opt), r_(r), holder_(opt.holder.empty() ? default_holder() : opt.holder) {}

  // --- the lease: one sweep at a time on a database ---
  bool take_lease() {
    const auto now = SystemClock::now();
    Transaction tx(impl_.db, Transaction::Kind::write);
    impl_.lock(Historian::Impl::LockSpace::retention, "sweep");  // PostgreSQL: the read and the take as one
    auto& held = impl_.stmt("SELECT holder, expires_at FROM retention_lease WHERE name = 'sweep'");
    if (held.step()) {
      const std::string holder = held.col_text(0), until = held.col_text(1);
      held.reset();
      if (holder != holder_ && until > utc_ms(now)) {
        r_.skipped = "another sweep holds the retention lease: " + holder + " until " + until;
        return false;
      }
    }
    impl_.stmt(
            "INSERT INTO retention_lease (name, holder, expires_at) VALUES ('sweep', ?, ?) "
            "ON CONFLICT (name) DO UPDATE SET holder = excluded.holder, expires_at = excluded.expires_at")
        .bind(1, holder_)
        .bind(2, utc_ms(now + opt_.lease_ttl))
        .run();
    tx.commit();
    renewed_ = SteadyClock::now();
    return true;
  }
  void release_lease() {
    Transaction tx(impl_.db, Transaction::Kind::write);
    impl_.stmt("UPDATE retention_lease SET expires_at = ? WHERE name = 'sweep' AND holder = ?")
        .bind(1, utc_ms(SystemClock::now()))
        .bind(2, holder_)
        .run();
    tx.commit();
  }

  // Between transactions: false when the sweep must stop (asked to, or
  // the lease was lost); renews the lease every third of its time.
  bool go_on() {
    if (r_.stopped) return false;
    if (opt_.stop && opt_.stop()) {
      r_.stopped = true;
      return false;
    }
    if (opt_.dry_run || SteadyClock::now() - renewed_ < opt_.lease_ttl / 3) return true;
    Transaction tx(impl_.db, Transaction::Kind::write);
    impl_.stmt("UPDATE retention_lease SET expires_at = ? WHERE name = 'sweep' AND holder = ?")
        .bind(1, utc_ms(SystemClock::now() + opt_.lease_ttl))
        .bind(2, holder_)
        .run();
    const bool held = impl_.db.changes() == 1;
    tx.commit();
    renewed_ = SteadyClock::now();
    if (!held) {
      r_.stopped = true;
      r_.errors.push_back("the retention lease was taken by another sweep (this one was paused past " +
                          std::to_string(opt_.lease_ttl.count()) + " s); stopped");
    }
    return held;
  }

  // The pumps with their newest own policy ("" when none), by id.
  std::vector<std::pair<std::string, std::string>> pumps() {
    auto& s = impl_.stmt(
        "SELECT p.pump_id, coalesce((SELECT policy_json FROM retention_policies r WHERE r.pump_id = p.pump_id "
        "ORDER BY version DESC LIMIT 1), '') FROM pumps p ORDER BY p.pump_id");
    std::vector<std::pair<std::string, std::string>> out;
    while (s.step()) out.emplace_back(s.col_text(0), s.col_text(1));
    return out;
  }

  // Drops a crashed sweep left half done.
  void finish_interrupted() {
    auto& s = impl_.stmt(
        "SELECT run_id, pump_id, (SELECT CAST(coalesce(sum(length(data)), 0) AS bigint) FROM sample_chunks c WHERE c.run_id = "
        "runs.run_id) "
        "FROM runs WHERE samples_state = 'dropping' ORDER BY run_id");
    std::vector<SweptRun> left;
    while (s.step()) left.push_back({s.col_text(0), s.col_text(1), "samples", s.col_int(2), "interrupted"});
    for (auto& run : left) {
      if (opt_.dry_run) {
        record(run);
        continue;
      }
      if (!go_on()) return;
      run.bytes = 0;
      drain(run.run_id, run.bytes);
      record(run);
    }
  }

  void pump(const std::string& pump_id, const RetentionPolicy& p) {
    ++r_.pumps;
    const std::set<std::string> planned = samples(pump_id, p);
    if (p.frf_days) frfs(pump_id, *p.frf_days, planned);
    if (p.monitoring_days) monitoring(pump_id, *p.monitoring_days);
  }

  // PostgreSQL: each past day partition of sample_chunks goes whole once
  // none of its runs is receiving and the runs it keeps (needed, or kept by
  // their pump's policy: younger than its samples_days, or no samples_days)
  // hold at most a quarter of its bytes. Those are moved to
  // sample_chunks_kept first, a transaction each (move_to_kept); then one
  // transaction marks the partition's other runs dropped with their bytes
  // and drops it (drop_day). A day whose kept runs hold more stays: its
  // other runs go row by row in pump(), as moving most of a day would cost
  // more than deleting the rest.
  void drop_partitions(const std::map<std::string, RetentionPolicy>& policies) {
    std::map<std::string, std::string> cutoff;  // pump -> created_at before which its samples go
    std::string latest;  // the latest cutoff: every policy keeps a run received at or after it
    for (const auto& [pump_id, p] : policies)
      if (p.samples_days) latest = std::max(latest, cutoff[pump_id] = utc_ms(days_before(opt_.now, *p.samples_days)));
    const std::string now = utc_ms(SystemClock::now());
    for (const auto& part : impl_.chunk_partitions()) {
      if (part.to > now) break;  // its day is not over: a run may still be received into it
      if (!go_on()) return;
      // Every run of a day from `latest` on is kept: such a partition with
      // chunks stays, without a look at its runs.
      if (part.from >= latest && holds_chunks(part)) continue;
      const DayPlan plan = plan_day(part, cutoff);
      if (plan.receiving || plan.kept_bytes * 4 > plan.bytes) continue;
      for (const auto& run : plan.kept) {
        if (!go_on()) return;
        move_to_kept(run);
      }
      if (!go_on()) return;
      drop_day(part, cutoff);
    }
  }

 private:
  struct KeptRun {
    std::string run_id;
    std::int64_t bytes;
  };
  // A day partition's runs (those received that day whose chunks were not
  // moved, and any with chunks in it) that are not dropped yet.
  struct DayPlan {
    bool receiving = false;      // one of them is: the day stays
    std::vector<KeptRun> kept;   // needed, or kept by the pump's policy
    std::int64_t kept_bytes = 0;  // theirs
    std::int64_t bytes = 0;      // all of them (received_frames * n_channels * 4; a `dropping` run's too)
  };

  DayPlan plan_day(const Historian::Impl::ChunkPartition& part, const std::map<std::string, std::string>& cutoff) {
    const std::string sql =
        "SELECT run_id, pump_id, created_at, samples_state, status, " AMBDIAG_RUN_NEEDED("runs.run_id") ", "
        "received_frames * n_channels * 4 FROM runs WHERE samples_state <> 'dropped' AND run_id IN (" +
        day_runs(part.name) + ")";
    auto s = impl_.db.prepare(sql.c_str(), Fetch::all);
    s->bind(1, part.from).bind(2, part.to);
    DayPlan plan;
    while (s->step()) {
      const std::int64_t bytes = s->col_int(6);
      plan.bytes += bytes;
      if (s->col_text(3) == "dropping") continue;  // already reads as dropped
      if (s->col_text(4) == "receiving") plan.receiving = true;
      const auto c = cutoff.find(s->col_text(1));
      if (s->col_int(5) != 0 || c == cutoff.end() || !(s->col_text(2) < c->second)) {
        plan.kept.push_back({s->col_text(0), bytes});
        plan.kept_bytes += bytes;
      }
    }
    return plan;
  }

  // SQL: the run_ids of the runs received on the partition's day (?1, ?2)
  // whose chunks are still in it, and of any run with chunks in `chunks`
  // (the partition, or a set of its rows).
  static std::string day_runs(const std::string& chunks) {
    return "SELECT run_id FROM runs WHERE created_at >= ?1 AND created_at < ?2 AND samples_kept_at IS NULL UNION "
           "SELECT run_id FROM " + chunks;
  }

  bool holds_chunks(const Historian::Impl::ChunkPartition& part) {
    auto s = impl_.db.prepare(("SELECT count(*) FROM (SELECT 1 FROM " + part.name + " LIMIT 1) x").c_str(), Fetch::all);
    return s->step() && s->col_int(0) > 0;
  }

  // One transaction: the run (not receiving, its samples held, not moved
  // yet) marked samples_kept_at and its chunks given the kept partition's
  // time, which PostgreSQL (>= 11) carries out as a move of the rows to
  // sample_chunks_kept. Row locks only: ingest of other runs goes on; the
  // run's own lock keeps its put_chunks (which reads samples_kept_at for
  // the key) before or after.
  void move_to_kept(const KeptRun& run) {
    write([&] {
      impl_.lock(Historian::Impl::LockSpace::run, run.run_id);
      impl_.stmt("UPDATE runs SET samples_kept_at = ? WHERE run_id = ? AND samples_state = 'held' AND status <> 'receiving' "
                 "AND samples_kept_at IS NULL")
          .bind(1, utc_ms(SystemClock::now()))
          .bind(2, run.run_id)
          .run();
      if (impl_.db.changes() != 1) return false;  // changed since the plan: drop_day's check sees it
      impl_.stmt("UPDATE sample_chunks SET run_created_at = CAST('" AMBDIAG_KEPT_CHUNKS_AT "' AS timestamptz) WHERE run_id = ?")
          .bind(1, run.run_id)
          .run();
      ++r_.moved_runs;
      r_.moved_bytes += run.bytes;
      return true;
    });
  }

  // The partition's drop, once its kept runs are moved: its runs marked
  // dropped with their bytes and DROP TABLE in one transaction. That
  // transaction holds sample_chunks and runs exclusively (DROP needs both,
  // runs for the foreign key), so new ingest transactions wait for its
  // length. Inside it the plan is made again: a run kept or receiving now
  // (a job queued, a reference set since the moves) keeps the partition
  // for the next sweep, which moves it.
  void drop_day(const Historian::Impl::ChunkPartition& part, const std::map<std::string, std::string>& cutoff) {
    std::vector<SweptRun> dropped;
    bool done = false;
    std::string why;
    // The locks are tried, never waited for: ingest holds runs and
    // sample_chunks in either order (a batch updates one run, then
    // inserts the next run's chunks), so a sweep waiting for one while
    // holding the other could deadlock with it. Tried again every 20 ms
    // for up to 5 s, then left to the next sweep.
    for (const auto until = SteadyClock::now() + std::chrono::seconds(5); !done;) {
      try {
        dropped.clear();
        done = write([&] {
          impl_.db.exec("LOCK TABLE sample_chunks IN ACCESS EXCLUSIVE MODE NOWAIT", "lock sample_chunks");
          impl_.db.exec("LOCK TABLE runs IN ACCESS EXCLUSIVE MODE NOWAIT", "lock runs");  // DROP's foreign key
          const DayPlan plan = plan_day(part, cutoff);
          if (plan.receiving || !plan.kept.empty()) return false;  // changed since the plan
          // Moved runs are not the day's any more (day_runs): not marked.
          const std::string sql =
              "WITH b AS (SELECT run_id, CAST(sum(length(data)) AS bigint) AS n FROM " + part.name +
              " GROUP BY run_id) UPDATE runs SET samples_state = 'dropped', samples_dropped_at = "
              "coalesce(samples_dropped_at, ?3), samples_dropped_bytes = samples_dropped_bytes + coalesce((SELECT n "
              "FROM b WHERE b.run_id = runs.run_id), 0) WHERE samples_state <> 'dropped' AND run_id IN (" +
              day_runs("b") + ") RETURNING run_id, pump_id, coalesce((SELECT n FROM b WHERE b.run_id = runs.run_id), 0)";
          auto mark = impl_.db.prepare(sql.c_str(), Fetch::all);
          const std::string at = utc_ms(SystemClock::now());  // bound by reference until the step
          mark->bind(1, part.from).bind(2, part.to).bind(3, at);
          while (mark->step()) dropped.push_back({mark->col_text(0), mark->col_text(1), "samples", mark->col_int(2), "age"});
          mark.reset();
          impl_.db.exec(("DROP TABLE " + part.name).c_str(), "drop a day partition of sample_chunks");
          return true;
        });
        if (!done) break;  // a run of it is kept now
      } catch (const StorageError& e) {
        why = e.what();
        const bool busy = why.find("55P03") != std::string::npos;  // lock_not_available
        if (!busy || SteadyClock::now() > until || !go_on()) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
    }
    if (!done) {
      if (!why.empty()) r_.errors.push_back("partition " + part.name + " not dropped (left to the next sweep): " + why);
      return;
    }
    ++r_.partitions;
    for (auto& run : dropped) {
      r_.samples_bytes += run.bytes;
      record(run);
    }
  }

  // The pump's runs whose samples the policy no longer keeps, oldest first
  // (by age, then by size while the pump holds more than samples_bytes);
  // dropped unless a dry run. Returns their ids.
  std::set<std::string> samples(const std::string& pump_id, const RetentionPolicy& p) {
    if (!p.samples_days && !p.samples_bytes) return {};
    const std::string cutoff = p.samples_days ? utc_ms(days_before(opt_.now, *p.samples_days)) : "";
    std::int64_t held = 0;  // the pump's samples held, receiving and needed runs included
    if (p.samples_bytes) {
      auto& t = impl_.stmt(
          "SELECT CAST(coalesce(sum(received_frames * n_channels * 4), 0) AS bigint) FROM runs WHERE pump_id = ? AND "
          "samples_state = 'held'");
      t.bind(1, pump_id).step();
      held = t.col_int(0);
      t.reset();
    }
    // Droppable runs, oldest first: all of them when a size is set, else
    // only those past the age.
    auto& s = p.samples_bytes
                  ? impl_.stmt("SELECT run_id, created_at, received_frames * n_channels * 4 FROM runs "
                               "WHERE pump_id = ?1 AND samples_state = 'held' AND status <> 'receiving' "
                               "AND NOT " AMBDIAG_RUN_NEEDED("runs.run_id") " ORDER BY created_at, run_id")
                  : impl_.stmt("SELECT run_id, created_at, received_frames * n_channels * 4 FROM runs "
                               "WHERE pump_id = ?1 AND samples_state = 'held' AND status <> 'receiving' AND created_at < ?2 "
                               "AND NOT " AMBDIAG_RUN_NEEDED("runs.run_id") " ORDER BY created_at, run_id");
    s.bind(1, pump_id);
    if (!p.samples_bytes) s.bind(2, cutoff);
    std::vector<SweptRun> plan;
    while (s.step()) {
      const std::string created_at = s.col_text(1);
      const std::int64_t bytes = s.col_int(2);
      const char* reason = !cutoff.empty() && created_at < cutoff ? "age" : p.samples_bytes && held > *p.samples_bytes ? "size" : nullptr;
      if (!reason) break;  // younger runs are not past the age either, and the size is met
      plan.push_back({s.col_text(0), pump_id, "samples", bytes, reason});
      held -= bytes;
    }
    s.reset();
    std::set<std::string> ids;
    for (auto& run : plan) {
      if (opt_.dry_run) {
        record(run);
        ids.insert(run.run_id);
        continue;
      }
      if (!go_on()) break;
      if (drop_samples(run)) ids.insert(run.run_id);
    }
    return ids;
  }

  // Marks the run dropping and deletes its first chunks; then the rest.
  // False when the run was no longer droppable (another sweep took it, a
  // job or alarm now needs it).
  bool drop_samples(SweptRun& run) {
    bool marked = false, done = false;
    std::int64_t bytes = 0;
    write([&] {
      // PostgreSQL: after a reference version being written for the pump
      // (the check below then sees it) and the run's ingest.
      impl_.lock(Historian::Impl::LockSpace::pump, run.pump_id);
      impl_.lock(Historian::Impl::LockSpace::run, run.run_id);
      impl_.stmt("UPDATE runs SET samples_state = 'dropping', samples_dropped_at = ?2 WHERE run_id = ?1 AND "
                 "samples_state = 'held' AND status <> 'receiving' AND NOT " AMBDIAG_RUN_NEEDED("?1"))
          .bind(1, run.run_id)
          .bind(2, utc_ms(SystemClock::now()))
          .run();
      if (impl_.db.changes() != 1) return false;
      marked = true;
      done = delete_batch(run.run_id, bytes);
      return true;
    });
    if (!marked) return false;
    if (!done) drain(run.run_id, bytes);
    run.bytes = bytes;
    record(run);
    return true;
  }

  // Deletes the chunks of a run marked dropping, a transaction per batch,
  // until none is left (true) or the sweep must stop (false).
  bool drain(const std::string& run_id, std::int64_t& bytes) {
    for (bool done = false; !done;) {
      if (!go_on()) return false;
      write([&] {
        done = delete_batch(run_id, bytes);
        return true;
      });
    }
    return true;
  }

  // Inside a write transaction: the run's first chunks up to
  // max_bytes_per_transaction (at least one); the run `dropped` when none
  // is left. Returns whether it is.
  bool delete_batch(const std::string& run_id, std::int64_t& bytes) {
    auto& sel = impl_.stmt("SELECT seq, length(data) FROM sample_chunks WHERE run_id = ? ORDER BY seq");
    sel.bind(1, run_id);
    std::int64_t last_seq = -1, batch = 0;
    bool more = false;
    while (sel.step()) {
      const std::int64_t n = sel.col_int(1);
      if (last_seq >= 0 && batch + n > opt_.max_bytes_per_transaction) {
        more = true;
        break;
      }
      last_seq = sel.col_int(0);
      batch += n;
    }
    sel.reset();
    if (last_seq >= 0) impl_.stmt("DELETE FROM sample_chunks WHERE run_id = ? AND seq <= ?").bind(1, run_id).bind(2, last_seq).run();
    impl_.stmt("UPDATE runs SET samples_dropped_bytes = samples_dropped_bytes + ?, samples_state = ? WHERE run_id = ?")
        .bind(1, batch)
        .bind(2, more ? "dropping" : "dropped")
        .bind(3, run_id)
        .run();
    bytes += batch;
    r_.samples_bytes += batch;
    return !more;
  }

  // The files of the analyses of runs received before now - days whose
  // samples are gone (or go in this dry run).
  void frfs(const std::string& pump_id, double days, const std::set<std::string>& planned) {
    auto& s = impl_.stmt(
        "SELECT run_id, samples_state FROM runs WHERE pump_id = ?1 AND frf_dropped_at IS NULL AND created_at < ?2 "
        "AND NOT " AMBDIAG_RUN_NEEDED("runs.run_id") " ORDER BY created_at, run_id");
    const std::string cutoff = utc_ms(days_before(opt_.now, days));
    s.bind(1, pump_id).bind(2, cutoff);
    std::vector<std::string> runs;
    while (s.step())
      if (s.col_text(1) == "dropped" || (opt_.dry_run && planned.count(s.col_text(0)))) runs.push_back(s.col_text(0));
    s.reset();
    for (const auto& run_id : runs) {
      SweptRun run{run_id, pump_id, "frf", 0, "age"};
      if (opt_.dry_run) {
        run.bytes = frf_bytes(run_id);
        record(run);
        continue;
      }
      if (!go_on()) return;
      const bool dropped = write([&] {
        impl_.stmt("UPDATE runs SET frf_dropped_at = ?2 WHERE run_id = ?1 AND frf_dropped_at IS NULL AND "
                   "samples_state = 'dropped' AND NOT " AMBDIAG_RUN_NEEDED("?1"))
            .bind(1, run_id)
            .bind(2, utc_ms(SystemClock::now()))
            .run();
        if (impl_.db.changes() != 1) return false;
        run.bytes = frf_bytes(run_id);
        impl_.stmt("DELETE FROM job_artifacts WHERE job_id IN (SELECT job_id FROM jobs WHERE run_id = ? AND kind = 'analysis')")
            .bind(1, run_id)
            .run();
        impl_.stmt("UPDATE runs SET frf_dropped_bytes = ? WHERE run_id = ?").bind(1, run.bytes).bind(2, run_id).run();
        return true;
      });
      if (dropped) record(run);
    }
  }

  std::int64_t frf_bytes(const std::string& run_id) {
    auto& s = impl_.stmt(
        "SELECT CAST(coalesce(sum(length(a.data)), 0) AS bigint) FROM job_artifacts a JOIN jobs j ON j.job_id = a.job_id "
        "WHERE j.run_id = ? AND j.kind = 'analysis'");
    s.bind(1, run_id).step();
    const auto n = s.col_int(0);
    s.reset();
    return n;
  }

  void monitoring(const std::string& pump_id, double days) {
    const auto cutoff = days_before(opt_.now, days);
    const std::int64_t cutoff_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(cutoff.time_since_epoch()).count();
    if (opt_.dry_run) {
      auto& s = impl_.stmt("SELECT count(*) FROM monitoring_snapshots WHERE pump_id = ? AND time_ns < ?");
      s.bind(1, pump_id).bind(2, cutoff_ns).step();
      r_.monitoring_rows += s.col_int(0);
      s.reset();
      return;
    }
    for (std::int64_t n = opt_.max_monitoring_rows_per_transaction; n == opt_.max_monitoring_rows_per_transaction;) {
      if (!go_on()) return;
      n = 0;
      write([&] {
        impl_.stmt("DELETE FROM monitoring_snapshots WHERE pump_id = ?1 AND time_ns IN (SELECT time_ns FROM "
                   "monitoring_snapshots WHERE pump_id = ?1 AND time_ns < ?2 ORDER BY time_ns LIMIT ?3)")
            .bind(1, pump_id)
            .bind(2, cutoff_ns)
            .bind(3, opt_.max_monitoring_rows_per_transaction)
            .run();
        n = impl_.db.changes();
        r_.monitoring_rows += n;
        return n > 0;
      });
    }
  }

  void record(const SweptRun& run) {
    if (run.what == "samples") {
      ++r_.samples_runs;
      if (opt_.dry_run) r_.samples_bytes += run.bytes;  // a real drop counted its batches
    } else {
      ++r_.frf_runs;
      r_.frf_bytes += run.bytes;
    }
    r_.runs.push_back(run);
  }

  // One write transaction around `body` (which says whether it dropped
  // something), timed: the time from BEGIN IMMEDIATE granted to COMMIT is
  // what a writer waiting for the lock (ingest) waits at most. Then a pause
  // as long as it, so such a writer gets its turn. Returns body's answer.
  template <class F>
  bool write(F&& body) {
    Transaction tx(impl_.db, Transaction::Kind::write);
    const auto t0 = SteadyClock::now();
    const bool dropped = body();
    tx.commit();
    const auto took = SteadyClock::now() - t0;
    if (dropped) {
      const double s = std::chrono::duration<double>(took).count();
      ++r_.transactions;
      r_.transactions_s += s;
      r_.longest_transaction_s = std::max(r_.longest_transaction_s, s);
      if (opt_.after_commit) opt_.after_commit();
    }
    if (opt_.yield_between_transactions) std::this_thread::sleep_for(std::max<SteadyClock::duration>(took, std::chrono::milliseconds(2)));
    return dropped;
  }

  Historian::Impl& impl_;
  const SweepOptions& opt_;
  SweepReport& r_;
  const std::string holder_;
  SteadyClock::time_point renewed_ = SteadyClock::now();
};

}  // namespace

int Historian::put_retention_policy(const std::string& pump_id, const std::string& policy_json,
                                    const std::string& created_by) {
  impl_->require_writer("put_retention_policy");
  const std::string ctx = "retention policy of pump " + quoted(pump_id);
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(policy_json);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(ctx + ": not JSON: " + e.what());
  }
  retention_policy_from_json(j, RetentionPolicy{}, ctx);  // InputError naming the key
  Transaction tx(impl_->db, Transaction::Kind::write);
  auto& known = impl_->stmt("SELECT 1 FROM pumps WHERE pump_id = ?");
  known.bind(1, pump_id);
  if (!known.step()) throw InputError(ctx + ": unknown pump");
  known.reset();
  const auto version = impl_->next_version("SELECT coalesce(max(version), 0) + 1 FROM retention_policies WHERE pump_id = ?", pump_id);
  impl_->stmt("INSERT INTO retention_policies (pump_id, version, policy_json, created_at, created_by) VALUES (?, ?, ?, ?, ?)")
      .bind(1, pump_id)
      .bind(2, version)
      .bind(3, j.dump())
      .bind(4, now_utc())
      .bind(5, created_by)
      .run();
  tx.commit();
  return static_cast<int>(version);
}

std::optional<RetentionVersion> Historian::find_retention_policy(const std::string& pump_id) {
  auto& s = impl_->stmt(
      "SELECT version, policy_json, created_at, created_by FROM retention_policies WHERE pump_id = ? "
      "ORDER BY version DESC LIMIT 1");
  s.bind(1, pump_id);
  if (!s.step()) return std::nullopt;
  auto v = read_version(s, pump_id);
  s.reset();
  return v;
}

std::vector<RetentionVersion> Historian::list_retention_policies(const std::string& pump_id) {
  auto& s = impl_->stmt(
      "SELECT version, policy_json, created_at, created_by FROM retention_policies WHERE pump_id = ? ORDER BY version");
  s.bind(1, pump_id);
  std::vector<RetentionVersion> out;
  while (s.step()) out.push_back(read_version(s, pump_id));
  return out;
}

RetentionPolicy Historian::effective_retention_policy(const std::string& pump_id, const RetentionPolicy& defaults) {
  const auto own = find_retention_policy(pump_id);
  if (!own) return defaults;
  return retention_policy_from_json(nlohmann::json::parse(own->policy_json), defaults,
                                    "retention policy version " + std::to_string(own->version) + " of pump " + quoted(pump_id));
}

RetentionUsage Historian::retention_usage(const std::string& pump_id) {
  auto& s = impl_->stmt(
      "SELECT count(*) FILTER (WHERE samples_state = 'held'), "
      "CAST(coalesce(sum(received_frames * n_channels * 4) FILTER (WHERE samples_state = 'held'), 0) AS bigint), "
      "count(*) FILTER (WHERE samples_state <> 'held'), CAST(coalesce(sum(samples_dropped_bytes), 0) AS bigint), "
      "count(*) FILTER (WHERE frf_dropped_at IS NOT NULL), CAST(coalesce(sum(frf_dropped_bytes), 0) AS bigint) "
      "FROM runs WHERE pump_id = ?");
  s.bind(1, pump_id).step();
  RetentionUsage u{s.col_int(0), s.col_int(1), s.col_int(2), s.col_int(3), s.col_int(4), s.col_int(5)};
  s.reset();
  return u;
}

SweepReport Historian::sweep_retention(const RetentionPolicy& defaults, const SweepOptions& options) {
  if (!options.dry_run) impl_->require_writer("sweep_retention");
  if (impl_->db.in_transaction()) throw std::logic_error("Historian::sweep_retention inside a transaction");
  if (options.max_bytes_per_transaction < 1 || options.max_monitoring_rows_per_transaction < 1 ||
      options.lease_ttl.count() < 1)
    throw std::invalid_argument("Historian::sweep_retention: the batch sizes and the lease time must be >= 1");
  const auto t0 = SteadyClock::now();
  SweepReport r;
  r.dry_run = options.dry_run;
  Sweep sweep(*impl_, options, r);
  // A dry run reads one committed state; a sweep takes the lease.
  std::optional<Transaction> snapshot;
  if (options.dry_run)
    snapshot.emplace(impl_->db, Transaction::Kind::read);
  else if (!sweep.take_lease())
    return r;
  try {
    sweep.finish_interrupted();
    std::map<std::string, RetentionPolicy> policies;  // pumps whose policy reads
    for (const auto& [pump_id, own] : sweep.pumps()) {
      try {
        policies.emplace(pump_id, own.empty() ? defaults
                                              : retention_policy_from_json(nlohmann::json::parse(own), defaults,
                                                                           "retention policy of pump " + quoted(pump_id)));
      } catch (const std::exception& e) {  // nothing of this pump is dropped on a guess
        r.errors.push_back(std::string(e.what()) + "; nothing of the pump dropped");
      }
    }
    if (impl_->dialect() == Dialect::postgres && !options.dry_run) {
      impl_->ensure_chunk_partitions(SystemClock::now());
      sweep.drop_partitions(policies);
    }
    for (const auto& [pump_id, p] : policies) {
      if (!sweep.go_on()) break;
      sweep.pump(pump_id, p);
    }
  } catch (...) {
    try {
      if (!options.dry_run) sweep.release_lease();
    } catch (const std::exception&) {  // the first failure is the one to report; the lease expires
    }
    throw;
  }
  if (!options.dry_run) sweep.release_lease();
  r.seconds = std::chrono::duration<double>(SteadyClock::now() - t0).count();
  return r;
}

}  // namespace ambdiag::storage
