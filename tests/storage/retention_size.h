// Steady streaming with a size policy, for the tests of the file's bound
// (retention_size_test.cc, retention_size_slow_test.cc): SQLite reuses the
// pages a sweep frees (no VACUUM), so the database file does not grow past
// the policy's amount plus what arrives between two sweeps and a little
// slack.
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "ambdiag/storage/historian.h"
#include "retention_fixture.h"
#include "test_support.h"

namespace ambdiag::storage {

struct SteadyStream {
  int pumps = 2;
  std::int64_t run_frames = 32768;  // of 2 channels: 256 KiB a run
  int runs_per_pump = 40;
  int runs_per_pump_kept = 4;       // the size policy, in runs
  int sweep_every = 4;              // runs per pump between sweeps
};

struct SteadyStreamFigures {
  std::int64_t budget_bytes = 0;     // the policies' amount, every pump
  std::int64_t between_sweeps = 0;   // what arrives between two sweeps
  std::int64_t written = 0;
  std::int64_t max_file_second_half = 0, file_at_half = 0, file_at_end = 0;
  std::int64_t freelist_at_end = 0;  // pages
};

inline std::int64_t file_bytes(const std::string& path) { return static_cast<std::int64_t>(std::filesystem::file_size(path)); }

// Streams the runs pump after pump, as the server's ingest commits them
// (a writer with background checkpoints), sweeping on a connection of its
// own every `sweep_every` runs of each pump.
inline SteadyStreamFigures stream_with_retention(const SteadyStream& s, const std::string& path) {
  auto writer = Historian::open(path);
  writer.checkpoint_in_background();
  auto sweeper = Historian::open(path);
  const std::int64_t run_bytes = s.run_frames * 2 * 4;
  RetentionPolicy policy;
  policy.samples_days.reset();
  policy.frf_days.reset();
  policy.samples_bytes = s.runs_per_pump_kept * run_bytes;
  SweepOptions opt;
  opt.yield_between_transactions = false;
  SteadyStreamFigures f;
  f.budget_bytes = s.pumps * *policy.samples_bytes;
  f.between_sweeps = s.pumps * s.sweep_every * run_bytes;
  for (int i = 0; i < s.runs_per_pump; ++i) {
    for (int p = 0; p < s.pumps; ++p) {
      const std::string pump = "P-" + std::to_string(p);
      store_run(writer, pump + "/r" + std::to_string(i), pump, s.run_frames, static_cast<unsigned>(i * 100 + p), 4096);
      f.written += run_bytes;
    }
    if ((i + 1) % s.sweep_every == 0) {
      const auto r = sweeper.sweep_retention(policy, opt);
      EXPECT_TRUE(r.skipped.empty()) << r.skipped;
    }
    const auto size = file_bytes(path);
    if (i + 1 == s.runs_per_pump / 2) f.file_at_half = size;
    if (i + 1 > s.runs_per_pump / 2) f.max_file_second_half = std::max(f.max_file_second_half, size);
  }
  f.file_at_end = file_bytes(path);
  f.freelist_at_end = raw_query_int(path, "PRAGMA freelist_count");
  for (int p = 0; p < s.pumps; ++p)
    EXPECT_LE(sweeper.retention_usage("P-" + std::to_string(p)).samples_bytes_held, *policy.samples_bytes + s.sweep_every * run_bytes);
  return f;
}

// The same in a scratch file, removed once the figures are taken (hundreds
// of MB in the slow version).
inline SteadyStreamFigures stream_with_retention(const SteadyStream& s) {
  const std::string path = (ambdiag::testing::scratch_dir() / "h.db").string();
  const SteadyStreamFigures f = stream_with_retention(s, path);
  for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(path + suffix);
  return f;
}

inline void expect_bounded(const SteadyStreamFigures& f) {
  std::printf("written %.1f MB, budget %.1f MB + %.1f MB between sweeps; file %.1f MB at half, %.1f MB at most after, "
              "%.1f MB at the end, %lld free pages\n",
              f.written / 1e6, f.budget_bytes / 1e6, f.between_sweeps / 1e6, f.file_at_half / 1e6,
              f.max_file_second_half / 1e6, f.file_at_end / 1e6, static_cast<long long>(f.freelist_at_end));
  EXPECT_GT(f.written, 4 * (f.budget_bytes + f.between_sweeps)) << "the stream must write several times the budget";
  // The policy's amount, what came since the last sweep, and 10 % + 1 MB for
  // the B-tree pages, the chunk index and the other tables.
  const double bound = 1.1 * static_cast<double>(f.budget_bytes + f.between_sweeps) + 1e6;
  EXPECT_LE(f.max_file_second_half, bound);
  // Not growing: the second half stays within a few pages of the first.
  EXPECT_LE(f.file_at_end, f.file_at_half + 64 * 4096);
}

}  // namespace ambdiag::storage
