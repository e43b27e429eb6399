// Helpers for the historian tests: a run.json text, seeded samples, chunks;
// the backends a test runs on.
#pragma once

#include <cstdint>
#include <cstring>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "ambdiag/core/checksum.h"
#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "pg_cluster.h"
#include "sqlite_raw.h"
#include "test_support.h"

namespace ambdiag::testing {

// A test of the historian's behaviour runs once per backend:
// TEST_P(SuiteTest, X) on a fixture derived from BackendTest, and
// AMBDIAG_ON_BOTH_BACKENDS(SuiteTest) gives Backends/SuiteTest.X/sqlite and
// Backends/SuiteTest.X/postgres. location() is a fresh SQLite file or a
// fresh schema of the test cluster (pg_cluster.h).
enum class Backend { sqlite, postgres };

class BackendTest : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    if (GetParam() == Backend::sqlite) {
      location_ = (scratch_dir() / "h.db").string();
      return;
    }
    const auto loc = postgres_test_location();
    if (!loc) GTEST_SKIP() << "AMBDIAG_NO_POSTGRES=1: the PostgreSQL backend is not tested";
    location_ = *loc;
  }
  // Where the test's historian is (Historian::open's location).
  const std::string& location() const { return location_; }
  bool postgres() const { return GetParam() == Backend::postgres; }

 private:
  std::string location_;
};

// An alarm of `rule` raised on `pump` (unack_active), as the engine writes one.
inline storage::AlarmRecord open_alarm(const std::string& pump, const std::string& rule) {
  storage::AlarmRecord a;
  a.pump_id = pump;
  a.rule = rule;
  a.severity = "high";
  a.state = "unack_active";
  a.active = true;
  a.raised_at = a.updated_at = "2026-11-26T10:00:00.000Z";
  a.run_id = pump + "/r1";
  a.message = "raised";
  a.fault = "balance_piston_wear";
  a.value = 1.7;
  return a;
}

// A journal entry of an alarm's transition.
inline storage::AlarmEvent alarm_event(const std::string& kind, const std::string& from, const std::string& to,
                                       const std::string& by = "server") {
  storage::AlarmEvent e;
  e.kind = kind;
  e.time = "2026-11-26T10:00:00.000Z";
  e.from = from;
  e.to = to;
  e.by = by;
  return e;
}

// The message of the InputError `f` throws ("" if none).
template <class F>
std::string input_error_of(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// SQL run on the historian's database behind its back, on either backend:
// the first column of the first row as an integer (-1 without a row).
inline std::int64_t raw_int(const std::string& location, const std::string& sql) {
  if (!storage::is_postgres_location(location)) return storage::raw_query_int(location, sql.c_str());
  const std::string v = pg_sql(location, sql);
  return v.empty() ? -1 : std::stoll(v);
}
// SQL run on the historian's database behind its back, on either backend
// (the test fails if it does).
inline void raw_run(const std::string& location, const std::string& sql) {
  if (!storage::is_postgres_location(location)) return storage::raw_exec(location, sql.c_str());
  pg_sql(location, sql);
}
// SQL that should fail: the database's error message, "" when it succeeded.
inline std::string raw_error(const std::string& location, const std::string& sql) {
  if (!storage::is_postgres_location(location)) return storage::raw_exec_error(location, sql.c_str());
  try {
    pg_sql(location, sql);
    return "";
  } catch (const std::exception& e) {
    return e.what();
  }
}

inline std::string backend_name(const ::testing::TestParamInfo<Backend>& info) {
  return info.param == Backend::sqlite ? "sqlite" : "postgres";
}

#define AMBDIAG_ON_BOTH_BACKENDS(Suite)                                                                           \
  INSTANTIATE_TEST_SUITE_P(Backends, Suite,                                                                       \
                           ::testing::Values(::ambdiag::testing::Backend::sqlite,                                 \
                                             ::ambdiag::testing::Backend::postgres),                              \
                           ::ambdiag::testing::backend_name)

inline std::string run_json_text(const std::string& run_id, int n_channels, const std::string& pump_id = "P-7",
                                 double speed_rpm = 3000.0) {
  nlohmann::json j = {{"format", "ambdiag.run/1"}, {"pump_id", pump_id},   {"run_id", run_id},
                      {"kind", "monitoring"},      {"started_at", "2026-11-21T10:00:00Z"},
                      {"speed_rpm", speed_rpm},    {"sample_rate_hz", 1000.0}};
  j["channels"] = nlohmann::json::array();
  for (int c = 0; c < n_channels; ++c)
    j["channels"].push_back({{"name", "x" + std::to_string(c)}, {"role", "displacement"}, {"unit", "m"}});
  return j.dump(2);
}

// The run.json text of an identification run (a one-segment multisine).
inline std::string identification_json_text(const std::string& run_id, const std::string& pump_id, int n_channels = 2) {
  auto j = nlohmann::json::parse(run_json_text(run_id, n_channels, pump_id));
  j["kind"] = "identification";
  j["excitation"] = {{"type", "multisine"},
                     {"period_samples", 100},
                     {"f_min_hz", 1.0},
                     {"f_max_hz", 400.0},
                     {"segments", {{{"start", 0}, {"periods", 3}, {"settle_periods", 1}, {"pattern", 0}}}}};
  return j.dump(2);
}

// A run's samples.f32 bytes: n_frames x n_channels seeded float32 values.
inline std::vector<std::uint8_t> samples_bytes(std::int64_t n_frames, int n_channels, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> d(0.0f, 1.0f);
  std::vector<float> v(static_cast<size_t>(n_frames * n_channels));
  for (auto& x : v) x = d(rng);
  std::vector<std::uint8_t> b(v.size() * sizeof(float));
  std::memcpy(b.data(), v.data(), b.size());
  return b;
}

// Cuts samples into chunks of `frames_per_chunk` frames, seq 0, 1, ...
inline std::vector<storage::Chunk> cut_chunks(std::span<const std::uint8_t> bytes, int n_channels,
                                              std::int64_t frames_per_chunk) {
  const std::int64_t frame_bytes = n_channels * 4;
  const std::int64_t n_frames = static_cast<std::int64_t>(bytes.size()) / frame_bytes;
  std::vector<storage::Chunk> out;
  for (std::int64_t f = 0, seq = 0; f < n_frames; f += frames_per_chunk, ++seq) {
    const std::int64_t n = std::min(frames_per_chunk, n_frames - f);
    out.push_back({seq, f, n, bytes.subspan(static_cast<size_t>(f * frame_bytes), static_cast<size_t>(n * frame_bytes))});
  }
  return out;
}

inline std::uint64_t checksum_of(std::span<const std::uint8_t> bytes) { return fnv1a64(bytes.data(), bytes.size()); }

inline std::string as_string(std::span<const std::uint8_t> b) {
  return std::string(reinterpret_cast<const char*>(b.data()), b.size());
}

}  // namespace ambdiag::testing

namespace ambdiag::storage {
using ::ambdiag::testing::input_error_of;
using ::ambdiag::testing::raw_error;
using ::ambdiag::testing::raw_int;
}  // namespace ambdiag::storage
