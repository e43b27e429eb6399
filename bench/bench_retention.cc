// bench_retention: what a retention sweep costs in SQLite, or PostgreSQL
// with --pg (docs/benchmarks.md, "Retention (issue 22)").
//
//   bench_retention [--runs N] [--run-mb M] [--seconds S] [--dir DIR] [--pg URI]
//
// 1. The sweep rate: N runs of M MB (32 KiB chunks, as the agents' blocks)
//    are stored, then one sweep drops them all: MB dropped per second of
//    wall and of CPU, transactions, the longest one. Twice: with the pages in
//    the page cache (just written) and cold (the file's cached pages dropped
//    with posix_fadvise first: a sweep drops runs received months ago).
// 2. Ingest beside the sweep: a writer thread commits 1 MiB of chunks at a
//    time (as the server's ingest, background checkpoints on) for S seconds,
//    alone and then while a sweep drops another N runs; each commit's time
//    (waiting for the write lock included) is what ingest waits.
// 3. PostgreSQL only: the same N runs moved into a past day's partition,
//    dropped whole by one sweep (its time is what ingest waits at most),
//    and ingest beside that sweep; then the same day with one run in 40
//    kept (a queued job names it): moved to sample_chunks_kept first, then
//    the day dropped whole. --pg URI: a database the bench may create the
//    schema ambdiag_bench_retention in (dropped first).
#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "ambdiag/core/checksum.h"
#include "ambdiag/core/process_memory.h"
#include "ambdiag/storage/historian.h"
#include "bench_util.h"
#include "libpq-fe.h"

namespace {

namespace fs = std::filesystem;
using ambdiag::storage::Chunk;
using ambdiag::storage::Historian;
using Clock = std::chrono::steady_clock;

constexpr int kChannels = 16;
constexpr std::int64_t kFramesPerChunk = 512;  // 16 x 4 x 512 = 32 KiB
constexpr std::size_t kChunkBytes = kChannels * 4 * kFramesPerChunk;

std::string header(const std::string& run_id, const std::string& pump) {
  std::string ch;
  for (int c = 0; c < kChannels; ++c)
    ch += std::string(c ? "," : "") + R"({"name": "x)" + std::to_string(c) + R"(", "role": "displacement", "unit": "m"})";
  return R"({"format": "ambdiag.run/1", "pump_id": ")" + pump + R"(", "run_id": ")" + run_id +
         R"(", "kind": "monitoring", "started_at": "2026-11-26T10:00:00Z", "speed_rpm": 3000, "sample_rate_hz": 10000, "channels": [)" +
         ch + "]}";
}

// Where the historian is: an SQLite file, or a schema of a PostgreSQL
// database made afresh by reset().
struct Target {
  fs::path file;
  std::string pg;  // the database's URI ("" for SQLite)
  static constexpr const char* kSchema = "ambdiag_bench_retention";
  bool postgres() const { return !pg.empty(); }
  std::string location() const {
    if (!postgres()) return file.string();
    return pg + (pg.find('?') == std::string::npos ? "?" : "&") + "options=-csearch_path%3D" + kSchema;
  }
  void sql(const std::string& statement, bool in_schema = true) const {
    PGconn* c = PQconnectdb((in_schema ? location() : pg).c_str());
    PQsetNoticeProcessor(c, [](void*, const char*) {}, nullptr);  // DROP ... CASCADE's list of tables
    PGresult* r = PQstatus(c) == CONNECTION_OK ? PQexec(c, statement.c_str()) : nullptr;
    const bool ok = r && (PQresultStatus(r) == PGRES_COMMAND_OK || PQresultStatus(r) == PGRES_TUPLES_OK);
    if (!ok) {
      std::fprintf(stderr, "bench_retention: %s: %s\n", statement.c_str(), PQerrorMessage(c));
      std::exit(1);
    }
    PQclear(r);
    PQfinish(c);
  }
  void reset() const {
    if (postgres())
      sql(std::string("DROP SCHEMA IF EXISTS ") + kSchema + " CASCADE; CREATE SCHEMA " + kSchema, false);
    else
      for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(file.string() + suffix);
  }
  // PostgreSQL: every run (and its chunks) as received 10 days ago, in that
  // day's partition, as runs received then are.
  void age_into_past_partition() const {
    const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now()) - 10 * 86400;
    std::tm tm{};
    gmtime_r(&t, &tm);
    char day[16], key[16];
    std::strftime(day, sizeof day, "%Y-%m-%d", &tm);
    std::strftime(key, sizeof key, "%Y%m%d", &tm);
    const std::string from = std::string("CAST('") + day + " 00:00:00+00' AS timestamptz)";
    sql(std::string("CREATE TABLE sample_chunks_d") + key + " PARTITION OF sample_chunks FOR VALUES FROM (" + from +
        ") TO (" + from + " + interval '1 day'); UPDATE runs SET created_at = '" + day +
        "T12:00:00.000Z'; UPDATE sample_chunks SET run_created_at = CAST('" + day + " 12:00:00+00' AS timestamptz)");
  }
};

struct Commit {
  Clock::time_point start;
  double seconds;
};

// A complete run of `n_chunks` chunks, committed `per_commit` chunks at a
// time; each commit's start and time into `commits` when given.
void store_run(Historian& h, const std::string& run_id, const std::string& pump, const std::vector<std::uint8_t>& data,
               std::size_t n_chunks, std::size_t per_commit, std::vector<Commit>* commits = nullptr) {
  h.begin_run(ambdiag::storage::run_header_from_json(header(run_id, pump)));
  std::uint64_t sum = ambdiag::kFnv1a64Init;
  for (std::size_t first = 0; first < n_chunks; first += per_commit) {
    std::vector<Chunk> chunks;
    for (std::size_t i = first; i < std::min(n_chunks, first + per_commit); ++i) {
      const auto bytes = std::span(data.data() + (i % 64) * kChunkBytes, kChunkBytes);
      chunks.push_back({static_cast<std::int64_t>(i), static_cast<std::int64_t>(i) * kFramesPerChunk, kFramesPerChunk, bytes});
      sum = ambdiag::fnv1a64(bytes.data(), bytes.size(), sum);
    }
    const auto t0 = Clock::now();
    h.put_chunks(run_id, chunks);
    if (commits) commits->push_back({t0, std::chrono::duration<double>(Clock::now() - t0).count()});
  }
  h.end_run(run_id, static_cast<std::int64_t>(n_chunks) * kFramesPerChunk, sum);
}

// Policy: samples older than `received_before` (and nothing else) dropped.
ambdiag::storage::RetentionPolicy drop_received_before(std::chrono::system_clock::time_point received_before) {
  ambdiag::storage::RetentionPolicy p;
  p.frf_days.reset();
  p.samples_days = std::chrono::duration<double>(std::chrono::system_clock::now() - received_before).count() / 86400.0;
  return p;
}

void drop_page_cache(const Target& t) {
  if (t.postgres()) return;  // the server's cache is not ours to drop
  const fs::path& path = t.file;
  for (const char* suffix : {"", "-wal"}) {
    const int fd = ::open((path.string() + suffix).c_str(), O_RDONLY);
    if (fd < 0) continue;
    ::fdatasync(fd);
    ::posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
    ::close(fd);
  }
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())))];
}

constexpr int kKeptEvery = 40;  // PostgreSQL's kept-run case: one run in 40 kept

// One sweep of `runs` stored runs: cold (SQLite: the file's pages dropped
// from the cache), or PostgreSQL's whole-partition drop (`partition`), with
// every `kept_every`-th run kept (a queued analysis names it; 0: none).
void sweep_rate(const Target& t, const std::vector<std::uint8_t>& data, int runs, std::size_t chunks_per_run, bool cold,
                bool partition = false, int kept_every = 0) {
  t.reset();
  {
    auto h = Historian::open(t.location());
    h.checkpoint_in_background();
    for (int r = 0; r < runs; ++r) {
      const std::string pump = "P-" + std::to_string(r % 4), run_id = pump + "/r" + std::to_string(r);
      store_run(h, run_id, pump, data, chunks_per_run, 256);
      if (kept_every && r % kept_every == 0) h.enqueue_job({"analysis", pump, run_id, 1, 0});
    }
  }
  if (partition) t.age_into_past_partition();
  const auto stored = std::chrono::system_clock::now();
  if (cold) drop_page_cache(t);
  auto h = Historian::open(t.location());
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const double c0 = ambdiag::bench::cpu_seconds(), w0 = ambdiag::bench::wall_seconds();
  ambdiag::storage::SweepOptions opt;
  opt.yield_between_transactions = false;  // the rate itself; the server yields as long as each transaction took
  const auto r = h.sweep_retention(drop_received_before(stored), opt);
  const double wall = ambdiag::bench::wall_seconds() - w0, cpu = ambdiag::bench::cpu_seconds() - c0;
  const double mb = static_cast<double>(r.samples_bytes) / 1e6;
  std::printf("sweep (%s, %s%s): %lld runs, %.0f MB dropped in %.2f s wall, %.2f s CPU: %.0f MB/s wall, %.0f MB per CPU-s; "
              "%lld partitions whole, %lld runs (%.0f MB) moved out first, %lld transactions, longest %.1f ms, mean %.1f ms\n",
              t.postgres() ? "PostgreSQL" : "SQLite", partition ? "a day partition" : cold ? "cold" : "warm",
              kept_every ? (", 1 run in " + std::to_string(kept_every) + " kept").c_str() : "",
              static_cast<long long>(r.samples_runs), mb, wall, cpu, mb / wall, mb / cpu, static_cast<long long>(r.partitions),
              static_cast<long long>(r.moved_runs), static_cast<double>(r.moved_bytes) / 1e6,
              static_cast<long long>(r.transactions), 1e3 * r.longest_transaction_s,
              1e3 * r.transactions_s / static_cast<double>(std::max<std::int64_t>(1, r.transactions)));
}

// The writer streams runs for `seconds`, one commit per 1 MiB; with
// `sweep`, another connection sweeps `runs` older runs meanwhile (every
// `kept_every`-th kept, as in sweep_rate).
void ingest_beside_sweep(const Target& t, const std::vector<std::uint8_t>& data, int runs, std::size_t chunks_per_run,
                         double seconds, bool sweep, bool partition = false, int kept_every = 0) {
  t.reset();
  {
    auto h = Historian::open(t.location());
    for (int r = 0; r < runs; ++r) {
      const std::string run_id = "P-9/old" + std::to_string(r);
      store_run(h, run_id, "P-9", data, chunks_per_run, 256);
      if (kept_every && r % kept_every == 0) h.enqueue_job({"analysis", "P-9", run_id, 1, 0});
    }
  }
  if (partition) t.age_into_past_partition();
  const auto stored = std::chrono::system_clock::now();
  drop_page_cache(t);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  std::vector<Commit> commits;
  ambdiag::storage::SweepReport report;
  Clock::time_point sweep_from{}, sweep_to{};
  std::thread sweeper([&] {
    if (!sweep) return;
    auto h = Historian::open(t.location());
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds / 4));  // ingest first runs alone
    sweep_from = Clock::now();
    report = h.sweep_retention(drop_received_before(stored));  // as the server: yielding between transactions
    sweep_to = Clock::now();
  });
  {
    auto h = Historian::open(t.location());
    h.checkpoint_in_background();
    const auto until = Clock::now() + std::chrono::duration<double>(seconds);
    for (int r = 0; Clock::now() < until; ++r) store_run(h, "P-1/new" + std::to_string(r), "P-1", data, chunks_per_run, 32, &commits);
  }
  sweeper.join();
  // With a sweep: the commits that began while it ran.
  std::vector<double> times;
  for (const auto& c : commits)
    if (!sweep || (c.start >= sweep_from && c.start <= sweep_to)) times.push_back(c.seconds);
  const double window = sweep ? std::chrono::duration<double>(sweep_to - sweep_from).count() : seconds;
  const double mb = static_cast<double>(times.size()) * 32 * kChunkBytes / 1e6;
  std::printf("ingest %s%s%s: %zu commits of 1 MiB in %.2f s (%.0f MB/s); commit time p50 %.1f ms, p99 %.1f ms, max %.1f ms\n",
              sweep ? "while a sweep ran" : "alone            ", partition ? " (a day partition" : "",
              !partition ? "" : kept_every ? ", its kept runs moved first)" : ")", times.size(), window, mb / std::max(1e-9, window),
              1e3 * ambdiag::bench::median(times), 1e3 * percentile(times, 0.99), 1e3 * percentile(times, 1.0));
  if (sweep) {
    const double sweep_wall = window;
    std::printf("  the sweep: %lld runs, %.0f MB in %.2f s (%.0f MB/s), %lld runs moved out first, %lld transactions, "
                "longest %.1f ms\n",
                static_cast<long long>(report.samples_runs), static_cast<double>(report.samples_bytes) / 1e6, sweep_wall,
                static_cast<double>(report.samples_bytes) / 1e6 / std::max(1e-9, sweep_wall),
                static_cast<long long>(report.moved_runs), static_cast<long long>(report.transactions),
                1e3 * report.longest_transaction_s);
  }
}

}  // namespace

int main(int argc, char** argv) {
  ambdiag::retain_freed_memory();
  int runs = 40;
  double run_mb = 6.0, seconds = 10.0;
  fs::path dir = fs::temp_directory_path() / "ambdiag-bench-retention";
  std::string pg;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--runs") runs = std::atoi(argv[i + 1]);
    else if (a == "--run-mb") run_mb = std::atof(argv[i + 1]);
    else if (a == "--seconds") seconds = std::atof(argv[i + 1]);
    else if (a == "--dir") dir = argv[i + 1];
    else if (a == "--pg") pg = argv[i + 1];
    else {
      std::fprintf(stderr, "usage: bench_retention [--runs N] [--run-mb M] [--seconds S] [--dir DIR] [--pg URI]\n");
      return 2;
    }
  }
  if (runs < 1 || !(run_mb > 0) || !(seconds > 0)) {
    std::fprintf(stderr, "bench_retention: --runs, --run-mb and --seconds must be > 0\n");
    return 2;
  }
  fs::create_directories(dir);
  const auto chunks_per_run = static_cast<std::size_t>(run_mb * 1e6 / static_cast<double>(kChunkBytes));
  std::vector<std::uint8_t> data(64 * kChunkBytes);
  for (std::size_t i = 0; i < data.size(); ++i) data[i] = static_cast<std::uint8_t>((i * 2654435761u) >> 13);
  const Target t{dir / "h.db", pg};
  std::printf("%d runs of %zu chunks of 32 KiB (%.1f MB) each\n", runs, chunks_per_run,
              static_cast<double>(chunks_per_run * kChunkBytes) / 1e6);
  sweep_rate(t, data, runs, chunks_per_run, false);
  sweep_rate(t, data, runs, chunks_per_run, true);
  ingest_beside_sweep(t, data, runs, chunks_per_run, seconds, false);
  ingest_beside_sweep(t, data, runs, chunks_per_run, seconds, true);
  if (t.postgres()) {
    sweep_rate(t, data, runs, chunks_per_run, false, true);
    ingest_beside_sweep(t, data, runs, chunks_per_run, seconds, true, true);
    sweep_rate(t, data, runs, chunks_per_run, false, true, kKeptEvery);
    ingest_beside_sweep(t, data, runs, chunks_per_run, seconds, true, true, kKeptEvery);
    t.sql(std::string("DROP SCHEMA ") + Target::kSchema + " CASCADE", false);
  } else {
    t.reset();
  }
  return 0;
}
