// Helpers for the retention tests: complete runs of seeded samples, and
// their reception time moved into the past behind the historian's back.
#pragma once

#include <chrono>
#include <cstdint>
#include <ctime>
#include <string>
#include <vector>

#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"
#include "sqlite_raw.h"

namespace ambdiag::storage {

// The historian's created_at format ("2026-11-26T10:00:00.000Z") of now - days.
inline std::string utc_days_ago(double days) {
  const auto at = std::chrono::system_clock::now() -
                  std::chrono::duration_cast<std::chrono::system_clock::duration>(std::chrono::duration<double, std::ratio<86400>>(days));
  const std::time_t t = std::chrono::system_clock::to_time_t(at);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S.000Z", &tm);
  return buf;
}

struct StoredRun {
  std::string run_id;
  std::vector<std::uint8_t> bytes;  // its samples.f32
};

// A complete run of `n_frames` seeded frames of 2 channels in chunks of
// `frames_per_chunk` (a monitoring run, or an identification run).
inline StoredRun store_run(Historian& h, const std::string& run_id, const std::string& pump_id, std::int64_t n_frames,
                           unsigned seed, std::int64_t frames_per_chunk = 1000, bool identification = false) {
  StoredRun r{run_id, ambdiag::testing::samples_bytes(n_frames, 2, seed)};
  h.begin_run(run_header_from_json(identification ? ambdiag::testing::identification_json_text(run_id, pump_id)
                                                  : ambdiag::testing::run_json_text(run_id, 2, pump_id)));
  const auto chunks = ambdiag::testing::cut_chunks(r.bytes, 2, frames_per_chunk);
  h.put_chunks(run_id, chunks);
  h.end_run(run_id, n_frames, ambdiag::testing::checksum_of(r.bytes));
  return r;
}

// The run as received at `created_at` (created_at's format), on either
// backend; on PostgreSQL its chunks move with it (to that day's partition
// if one exists, else to the default one).
inline void received_at(const std::string& location, const std::string& run_id, const std::string& created_at) {
  const std::string where = " WHERE run_id = '" + run_id + "'";
  ambdiag::testing::raw_run(location, "UPDATE runs SET created_at = '" + created_at + "'" + where);
  if (is_postgres_location(location))
    ambdiag::testing::raw_run(location,
                              "UPDATE sample_chunks SET run_created_at = CAST('" + created_at + "' AS timestamptz)" + where);
}

// The run as received `days` ago.
inline void received_days_ago(const std::string& location, const std::string& run_id, double days) {
  received_at(location, run_id, utc_days_ago(days));
}

inline std::int64_t chunks_held(const std::string& location, const std::string& run_id) {
  return ambdiag::testing::raw_int(location, "SELECT count(*) FROM sample_chunks WHERE run_id = '" + run_id + "'");
}

inline std::string samples_state(Historian& h, const std::string& run_id) {
  const auto r = h.find_run(run_id);
  return !r ? "unknown" : r->samples_dropped_at ? "dropped" : "held";
}

// A policy of samples by age only (nothing else dropped).
inline RetentionPolicy samples_for_days(double days) {
  RetentionPolicy p;
  p.samples_days = days;
  p.frf_days.reset();
  return p;
}

}  // namespace ambdiag::storage
