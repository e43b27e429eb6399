// A pump's trend series (schema v5, docs/storage.md "Series"): the values
// each analysed run contributes (kept with the analysis job's result, in the
// same transaction) and the monitoring snapshots' values (read from table
// monitoring_snapshots, not copied). The Historian's methods that write and
// read them are declared in historian.h and implemented in
// historian_trends.cc; which values a run gives is the server's business
// (server/src/trends/run_series.h), storage only keeps them.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace ambdiag::storage {

// One value a run gives one of its pump's series.
struct SeriesValue {
  std::string name;  // e.g. "mode.radial bending 1 (forward).f_hz"
  std::string unit;  // "Hz", "1", "rpm", ...
  double value = 0.0;
  std::optional<double> sd;  // one standard deviation, where the analysis gives one
};

struct SeriesInfo {
  std::string name, unit;
};

// A stored point: a run's value at the run's start (started_at), or a
// monitoring snapshot's value at its time (run_id empty).
struct TrendPoint {
  std::int64_t time_ns = 0;
  double value = 0.0;
  std::optional<double> sd;
  std::string run_id;
};

// The points of one time bucket [time_ns, time_ns + bucket_ns): the extremes
// (so no peak is lost when drawn) and the first and last in time.
struct TrendBucket {
  std::int64_t time_ns = 0;
  double min = 0.0, max = 0.0, first = 0.0, last = 0.0;
  std::int64_t count = 0;
};

struct TrendQuery {
  std::int64_t from_ns = std::numeric_limits<std::int64_t>::min();  // inclusive
  std::int64_t to_ns = std::numeric_limits<std::int64_t>::max();    // inclusive
  std::int64_t max_points = 1000;  // >= 1
  // false: more than max_points points become at most max_points buckets.
  // true: the first max_points points only, and where to go on.
  bool raw = false;
};

struct Trend {
  SeriesInfo series;
  std::int64_t count = 0;            // points in the range
  std::vector<TrendPoint> points;    // oldest first (count <= max_points, or raw)
  std::vector<TrendBucket> buckets;  // oldest first, only the non-empty ones (otherwise)
  std::int64_t bucket_ns = 0;        // the buckets' width (0 without buckets)
  // raw only: the range held more than max_points points; the next page
  // starts at next_from_ns (inclusive; no point of this page has that time).
  bool truncated = false;
  std::optional<std::int64_t> next_from_ns;
};

}  // namespace ambdiag::storage
