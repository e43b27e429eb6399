// The job queue's own throughput (issue 22): empty jobs, so what is
// measured is the queue (SQLite transactions, the claim's pick, the fence),
// not an analysis. For each number of workers W: a fresh historian file,
// N jobs enqueued one transaction each (as the ingest queues runs), then W
// threads, each with its own connection (as W processes would have), claim
// with a lease and finish until the queue is empty; every job must be done
// once. Prints jobs/s of the enqueue and of claim + finish, and the CPU.
// With --pg URI the same on PostgreSQL: a fresh schema ambdiag_bench_jobs
// of that database for each measurement (dropped at the end), claims with
// SELECT ... FOR UPDATE SKIP LOCKED; the CPU is this process' (the
// clients'), PostgreSQL's server processes' is not in it.
//
// Usage: bench_jobs [--jobs N] [--workers 1,2,4] [--reps R] [--dir DIR | --pg URI]
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "ambdiag/core/process_memory.h"
#include "ambdiag/storage/historian.h"
#include "bench_pg.h"
#include "bench_util.h"

namespace {

using ambdiag::storage::Historian;
using ambdiag::storage::JobKey;
using ambdiag::storage::JobStatus;

struct Figures {
  double enqueue_per_s = 0, drain_per_s = 0, drain_cpu_s = 0;
  bool once = true;
};

constexpr const char* kSchema = "ambdiag_bench_jobs";

// A fresh, empty historian at `path`: the file removed, or the schema dropped.
void remove_historian(const std::string& path, const std::string& pg_uri, bool recreate) {
  if (pg_uri.empty()) {
    std::filesystem::remove(path);
    std::filesystem::remove(path + "-wal");
    std::filesystem::remove(path + "-shm");
    return;
  }
  ambdiag::bench::PgConn admin("bench_jobs", pg_uri);
  admin.exec(std::string("DROP SCHEMA IF EXISTS ") + kSchema + " CASCADE");
  if (recreate) admin.exec(std::string("CREATE SCHEMA ") + kSchema);
}

Figures measure(const std::string& path, const std::string& pg_uri, int jobs, int workers) {
  remove_historian(path, pg_uri, true);
  Figures f;
  {
    auto h = Historian::open(path);
    const double t0 = ambdiag::bench::wall_seconds();
    for (int i = 0; i < jobs; ++i) h.enqueue_job(JobKey{"analysis", "P-" + std::to_string(i % 100), "run-" + std::to_string(i), 1, 0});
    f.enqueue_per_s = jobs / (ambdiag::bench::wall_seconds() - t0);
  }
  std::vector<std::thread> threads;
  std::atomic<int> ready{0}, refused{0};
  const double cpu0 = ambdiag::bench::cpu_seconds();
  double t0 = 0;
  for (int w = 0; w < workers; ++w)
    threads.emplace_back([&, w] {
      auto h = Historian::open(path);
      const std::string name = "bench/worker-" + std::to_string(w);
      if (++ready == workers) t0 = ambdiag::bench::wall_seconds();
      while (ready < workers) std::this_thread::yield();
      while (const auto job = h.claim_job(name))
        if (!h.finish_job(job->job_id, job->attempts, "{}")) ++refused;
    });
  for (auto& t : threads) t.join();
  f.drain_per_s = jobs / (ambdiag::bench::wall_seconds() - t0);
  f.drain_cpu_s = ambdiag::bench::cpu_seconds() - cpu0;
  auto h = Historian::open(path, Historian::Mode::read);
  f.once = refused == 0 && h.count_jobs(JobStatus::done) == jobs;
  for (const auto& j : h.list_jobs({std::nullopt, std::nullopt, std::nullopt, std::nullopt, jobs}))
    f.once = f.once && j.attempts == 1;
  return f;
}

}  // namespace

int main(int argc, char** argv) {
  ambdiag::retain_freed_memory();
  int jobs = 5000, reps = 3;
  std::vector<int> worker_counts = {1, 2, 4};
  std::string dir = std::filesystem::temp_directory_path().string(), pg_uri;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool more = i + 1 < argc;
    if (a == "--jobs" && more) {
      jobs = std::atoi(argv[++i]);
    } else if (a == "--reps" && more) {
      reps = std::atoi(argv[++i]);
    } else if (a == "--dir" && more) {
      dir = argv[++i];
    } else if (a == "--pg" && more) {
      pg_uri = argv[++i];
      if (!ambdiag::storage::is_postgres_location(pg_uri)) {
        std::fprintf(stderr, "bench_jobs: --pg: not a PostgreSQL URI (postgresql://...)\n");
        return 2;
      }
    } else if (a == "--workers" && more) {
      worker_counts.clear();
      std::istringstream list(argv[++i]);
      for (std::string n; std::getline(list, n, ',');) worker_counts.push_back(std::atoi(n.c_str()));
    } else {
      std::fprintf(stderr, "usage: bench_jobs [--jobs N] [--workers 1,2,4] [--reps R] [--dir DIR | --pg URI]\n");
      return 2;
    }
  }
  if (jobs < 1 || reps < 1 || worker_counts.empty()) {
    std::fprintf(stderr, "bench_jobs: --jobs, --reps and the worker counts must be >= 1\n");
    return 2;
  }
  const std::string path = pg_uri.empty() ? dir + "/bench_jobs.db"
                                          : ambdiag::bench::pg_schema_location(pg_uri, kSchema, "bench_jobs");
  std::printf("%d empty jobs, %d repetitions (medians); %s\n", jobs, reps,
              pg_uri.empty() ? ("file " + path).c_str()
                             : ("PostgreSQL " + ambdiag::bench::PgConn("bench_jobs", pg_uri).exec("SHOW server_version") +
                                ", schema " + kSchema + " of " + ambdiag::storage::display_location(pg_uri))
                                   .c_str());
  std::printf("%8s %16s %22s %16s %10s\n", "workers", "enqueue jobs/s", "claim+finish jobs/s", "CPU s (drain)", "once");
  bool all_once = true;
  for (const int w : worker_counts) {
    if (w < 1) continue;
    std::vector<double> enq, drain, cpu;
    bool once = true;
    for (int r = 0; r < reps; ++r) {
      const auto f = measure(path, pg_uri, jobs, w);
      enq.push_back(f.enqueue_per_s);
      drain.push_back(f.drain_per_s);
      cpu.push_back(f.drain_cpu_s);
      once = once && f.once;
    }
    all_once = all_once && once;
    std::printf("%8d %16.0f %22.0f %16.2f %10s\n", w, ambdiag::bench::median(enq), ambdiag::bench::median(drain),
                ambdiag::bench::median(cpu), once ? "yes" : "NO");
  }
  remove_historian(path, pg_uri, false);
  return all_once ? 0 : 1;
}
