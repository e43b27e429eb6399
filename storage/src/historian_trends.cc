// Historian: trend series (tables series, series_points, series_runs,
// schema v5; monitoring values read from monitoring_snapshots).
#include <algorithm>
#include <cmath>

#include <nlohmann/json.hpp>

#include "ambdiag/storage/historian.h"
#include "historian_impl.h"

namespace ambdiag::storage {

namespace {

// A monitoring value as a series: "monitoring." + the snapshot's field,
// with ".ax" / ".a" for the bearing axis or bearing (monitoring.h's order),
// read straight from its column. Its statements are built once, so their
// text has a stable address (the statement cache's key).
struct MonitoringSeries {
  SeriesInfo info;
  std::string count_sql, last_sql, points_sql, values_sql;
};

const std::vector<MonitoringSeries>& monitoring_series() {
  static const std::vector<MonitoringSeries> all = [] {
    std::vector<std::pair<std::string, std::string>> cols = {{"speed_rpm", "rpm"}};  // (column, unit)
    for (const char* f : {"force_1x_amp_n", "force_1x_phase_rad", "force_2x_amp_n", "force_2x_phase_rad"})
      for (const char* axis : {"ax", "ay", "bx", "by"})
        cols.emplace_back(std::string(f) + "_" + axis, std::string(f).ends_with("_n") ? "N" : "rad");
    for (const char* f : {"orbit_major_m", "orbit_minor_m", "orbit_center_x_m", "orbit_center_y_m"})
      for (const char* bearing : {"a", "b"}) cols.emplace_back(std::string(f) + "_" + bearing, "m");
    std::vector<MonitoringSeries> out;
    for (const auto& [col, unit] : cols) {
      std::string name = "monitoring." + col;
      if (col != "speed_rpm") name[name.rfind('_')] = '.';  // force_1x_amp_n_ax -> force_1x_amp_n.ax
      out.push_back({{name, unit},
                     "SELECT count(*) FROM monitoring_snapshots WHERE pump_id = ?1 AND time_ns BETWEEN ?2 AND ?3",
                     "SELECT time_ns FROM monitoring_snapshots WHERE pump_id = ?1 AND time_ns BETWEEN ?2 AND ?3 "
                     "ORDER BY time_ns DESC LIMIT 1",
                     "SELECT time_ns, " + col + ", NULL, '' FROM monitoring_snapshots WHERE pump_id = ?1 "
                     "AND time_ns BETWEEN ?2 AND ?3 ORDER BY time_ns LIMIT ?4",
                     "SELECT time_ns, " + col + " FROM monitoring_snapshots WHERE pump_id = ?1 "
                     "AND time_ns BETWEEN ?2 AND ?3 ORDER BY time_ns"});
    }
    return out;
  }();
  return all;
}

constexpr const char* kSeriesCountSql =
    "SELECT count(*) FROM series_points WHERE series_id = ?1 AND time_ns BETWEEN ?2 AND ?3";
constexpr const char* kSeriesLastSql =
    "SELECT time_ns FROM series_points WHERE series_id = ?1 AND time_ns BETWEEN ?2 AND ?3 ORDER BY time_ns DESC LIMIT 1";
constexpr const char* kSeriesPointsSql =
    "SELECT time_ns, value, sd, run_id FROM series_points WHERE series_id = ?1 AND time_ns BETWEEN ?2 AND ?3 "
    "ORDER BY time_ns, run_id LIMIT ?4";
// For buckets: time and value only (no run_id text to copy per row).
constexpr const char* kSeriesValuesSql =
    "SELECT time_ns, value FROM series_points WHERE series_id = ?1 AND time_ns BETWEEN ?2 AND ?3 ORDER BY time_ns";

// Where a series' points are read from: its rows of series_points, or a
// column of the pump's monitoring snapshots.
struct Source {
  SeriesInfo info;
  const char* count_sql = kSeriesCountSql;
  const char* last_sql = kSeriesLastSql;
  const char* points_sql = kSeriesPointsSql;
  const char* values_sql = kSeriesValuesSql;
  std::optional<std::int64_t> series_id;  // nullopt: monitoring (bound by pump_id)
};

TrendPoint read_point(const Stmt& s) {
  TrendPoint p{s.col_int(0), s.col_double(1), std::nullopt, s.col_text(3)};
  if (!s.col_null(2)) p.sd = s.col_double(2);
  return p;
}

}  // namespace

bool put_run_series(Historian::Impl& impl, std::int64_t job_id, const std::string& pump_id, const std::string& run_id,
                    const std::vector<SeriesValue>& values) {
  impl.lock(Historian::Impl::LockSpace::run, run_id);  // the newer-job check stays true until the writes
  auto& run = impl.stmt("SELECT started_at FROM runs WHERE run_id = ? AND pump_id = ?");
  run.bind(1, run_id).bind(2, pump_id);
  if (!run.step()) return false;  // a job of a run the historian does not hold: no time to put it at
  const std::string started_at = run.col_text(0);
  run.reset();
  std::int64_t time_ns = 0;
  try {
    time_ns = ns_from_utc(started_at, "started_at");
  } catch (const InputError&) {
    return false;  // run.json's started_at is checked at ingest; an older odd one has no place on a time axis
  }
  auto& held = impl.stmt("SELECT job_id FROM series_runs WHERE run_id = ?");
  held.bind(1, run_id);
  const bool newer_held = held.step() && held.col_int(0) > job_id;
  held.reset();
  if (newer_held) return false;  // a later analysis of the run (newer model or reference) stays
  impl.stmt("DELETE FROM series_points WHERE run_id = ?").bind(1, run_id).run();
  for (const auto& v : values) {
    auto& cat = impl.stmt(
        "INSERT INTO series (pump_id, name, unit) VALUES (?, ?, ?) "
        "ON CONFLICT (pump_id, name) DO UPDATE SET unit = excluded.unit RETURNING series_id");
    cat.bind(1, pump_id).bind(2, v.name).bind(3, v.unit);
    if (!cat.step()) throw StorageError("series " + quoted(v.name) + ": the catalogue returned no series_id");
    const std::int64_t series_id = cat.col_int(0);
    cat.reset();
    auto& ins = impl.stmt(
        "INSERT INTO series_points (series_id, time_ns, run_id, value, sd) VALUES (?, ?, ?, ?, ?) "
        "ON CONFLICT DO NOTHING");
    ins.bind(1, series_id).bind(2, time_ns).bind(3, run_id).bind(4, v.value);
    if (v.sd)
      ins.bind(5, *v.sd);
    else
      ins.bind_null(5);
    ins.run();
  }
  impl.stmt("INSERT INTO series_runs (run_id, job_id) VALUES (?, ?) ON CONFLICT (run_id) DO UPDATE SET job_id = excluded.job_id")
      .bind(1, run_id)
      .bind(2, job_id)
      .run();
  return true;
}

void check_series_values(const std::vector<SeriesValue>& values, const std::string& what) {
  for (const auto& v : values) {
    if (v.name.empty()) throw InputError(what + ": a series without a name");
    if (!std::isfinite(v.value)) throw InputError(what + ": series " + quoted(v.name) + ": value is not finite");
    if (v.sd && !(std::isfinite(*v.sd) && *v.sd >= 0.0))
      throw InputError(what + ": series " + quoted(v.name) + ": sd is not a finite non-negative number");
  }
}

int Historian::backfill_series(const std::function<std::vector<SeriesValue>(const std::string&)>& series_of) {
  impl_->require_writer("backfill_series");
  int filled = 0;
  std::int64_t after = 0;
  // In batches by job_id, each its own transaction: a large history does
  // not hold the write lock for long, and what is done stays done.
  for (;;) {
    Transaction tx(impl_->db, Transaction::Kind::write);
    auto& pick = impl_->stmt(
        "SELECT j.job_id, j.pump_id, j.run_id, j.result FROM jobs j "
        "WHERE j.kind = 'analysis' AND j.status = 'done' AND j.run_id <> '' AND j.result IS NOT NULL AND j.job_id > ?1 "
        "AND j.job_id = (SELECT max(k.job_id) FROM jobs k WHERE k.run_id = j.run_id AND k.kind = 'analysis' "
        "AND k.status = 'done') "
        "AND NOT EXISTS (SELECT 1 FROM series_runs s WHERE s.run_id = j.run_id AND s.job_id >= j.job_id) "
        "ORDER BY j.job_id LIMIT 200");
    pick.bind(1, after);
    struct Todo {
      std::int64_t job_id;
      std::string pump_id, run_id, result;
    };
    std::vector<Todo> todo;
    while (pick.step()) todo.push_back({pick.col_int(0), pick.col_text(1), pick.col_text(2), pick.col_text(3)});
    if (todo.empty()) return filled;
    for (const auto& t : todo) {
      const auto values = series_of(t.result);
      check_series_values(values, "backfill_series job " + std::to_string(t.job_id));
      filled += put_run_series(*impl_, t.job_id, t.pump_id, t.run_id, values);
    }
    after = todo.back().job_id;
    tx.commit();
  }
}

std::vector<SeriesInfo> Historian::list_series(const std::string& pump_id) {
  Transaction tx(impl_->db, Transaction::Kind::read);
  std::vector<SeriesInfo> out;
  auto& s = impl_->stmt("SELECT name, unit FROM series WHERE pump_id = ? ORDER BY name");
  s.bind(1, pump_id);
  while (s.step()) out.push_back({s.col_text(0), s.col_text(1)});
  auto& m = impl_->stmt("SELECT 1 FROM monitoring_snapshots WHERE pump_id = ? LIMIT 1");
  m.bind(1, pump_id);
  const bool monitored = m.step();
  m.reset();
  if (monitored)
    for (const auto& ms : monitoring_series()) out.push_back(ms.info);
  std::sort(out.begin(), out.end(), [](const SeriesInfo& a, const SeriesInfo& b) { return a.name < b.name; });
  return out;
}

std::optional<Trend> Historian::query_trend(const std::string& pump_id, const std::string& name, const TrendQuery& q) {
  if (q.max_points < 1) throw InputError("query_trend: max_points must be >= 1");
  if (q.from_ns > q.to_ns) throw InputError("query_trend: from is after to");
  Transaction tx(impl_->db, Transaction::Kind::read);  // count and points from one snapshot
  std::optional<Source> src;
  auto& cat = impl_->stmt("SELECT series_id, unit FROM series WHERE pump_id = ? AND name = ?");
  cat.bind(1, pump_id).bind(2, name);
  if (cat.step()) src = Source{{name, cat.col_text(1)}, kSeriesCountSql, kSeriesLastSql, kSeriesPointsSql, kSeriesValuesSql, cat.col_int(0)};
  cat.reset();
  if (!src && name.starts_with("monitoring."))
    for (const auto& ms : monitoring_series())
      if (ms.info.name == name) {
        auto& m = impl_->stmt("SELECT 1 FROM monitoring_snapshots WHERE pump_id = ? LIMIT 1");
        m.bind(1, pump_id);
        if (m.step()) src = Source{ms.info, ms.count_sql.c_str(), ms.last_sql.c_str(), ms.points_sql.c_str(), ms.values_sql.c_str(), std::nullopt};
        m.reset();
      }
  if (!src) return std::nullopt;
  const auto bind_range = [&](Stmt& s) -> Stmt& {
    if (src->series_id)
      s.bind(1, *src->series_id);
    else
      s.bind(1, pump_id);
    return s.bind(2, q.from_ns).bind(3, q.to_ns);
  };

  Trend t;
  t.series = src->info;
  // One more than max_points: fewer is the whole answer, without a count.
  auto& s = bind_range(impl_->stmt(src->points_sql));
  s.bind(4, q.max_points + 1);
  while (s.step()) t.points.push_back(read_point(s));
  s.reset();
  t.count = static_cast<std::int64_t>(t.points.size());
  if (t.count <= q.max_points) return t;
  if (q.raw) {
    auto& c = bind_range(impl_->stmt(src->count_sql));
    c.step();
    t.count = c.col_int(0);
    c.reset();
    // The next page starts at the first time not shown; points of this
    // page at that time go to the next one too, so none is shown twice.
    const std::int64_t next = t.points[static_cast<size_t>(q.max_points)].time_ns;
    t.points.resize(static_cast<size_t>(q.max_points));
    auto keep = t.points.size();
    while (keep > 0 && t.points[keep - 1].time_ns == next) --keep;
    // More than max_points points at one time: shown here, the next page after them.
    if (keep == 0) {
      t.next_from_ns = next + 1;
    } else {
      t.points.resize(keep);
      t.next_from_ns = next;
    }
    t.truncated = true;
    return t;
  }
  const std::int64_t first_ns = t.points.front().time_ns;
  t.points.clear();
  auto& l = bind_range(impl_->stmt(src->last_sql));
  l.step();
  const std::int64_t last_ns = l.col_int(0);
  l.reset();
  // Equal buckets over the points' extent in the range: width > span /
  // max_points, so there are at most max_points. Unsigned: the span of two
  // int64 times may exceed int64.
  const auto span = static_cast<std::uint64_t>(last_ns) - static_cast<std::uint64_t>(first_ns);
  const std::uint64_t width = span / static_cast<std::uint64_t>(q.max_points) + 1;
  t.bucket_ns = static_cast<std::int64_t>(std::min<std::uint64_t>(width, static_cast<std::uint64_t>(INT64_MAX)));
  auto& v = bind_range(impl_->stmt(src->values_sql));
  std::uint64_t current = UINT64_MAX;
  while (v.step()) {
    const std::int64_t time_ns = v.col_int(0);
    const double value = v.col_double(1);
    const std::uint64_t idx = (static_cast<std::uint64_t>(time_ns) - static_cast<std::uint64_t>(first_ns)) / width;
    if (idx != current) {
      current = idx;
      t.buckets.push_back({static_cast<std::int64_t>(static_cast<std::uint64_t>(first_ns) + idx * width), value, value,
                           value, value, 0});
    }
    auto& b = t.buckets.back();
    b.min = std::min(b.min, value);
    b.max = std::max(b.max, value);
    b.last = value;
    ++b.count;
  }
  v.reset();
  t.count = 0;
  for (const auto& b : t.buckets) t.count += b.count;
  return t;
}

std::vector<TrendPoint> Historian::run_points(const std::string& pump_id, const std::string& name,
                                              const std::vector<std::string>& run_ids) {
  const std::string ids = nlohmann::json(run_ids).dump();
  // The ids as a JSON array: SQLite's json_each, PostgreSQL's json_array_elements_text.
  auto& s = impl_->dialect() == Dialect::postgres
                ? impl_->stmt(
                      "SELECT p.time_ns, p.value, p.sd, p.run_id FROM series s JOIN series_points p ON p.series_id = "
                      "s.series_id WHERE s.pump_id = ?1 AND s.name = ?2 AND p.run_id IN (SELECT value FROM "
                      "json_array_elements_text(CAST(?3 AS json))) ORDER BY p.time_ns, p.run_id")
                : impl_->stmt(
                      "SELECT p.time_ns, p.value, p.sd, p.run_id FROM series s JOIN series_points p ON p.series_id = "
                      "s.series_id WHERE s.pump_id = ?1 AND s.name = ?2 AND p.run_id IN (SELECT value FROM "
                      "json_each(?3)) ORDER BY p.time_ns, p.run_id");
  s.bind(1, pump_id).bind(2, name).bind(3, ids);
  std::vector<TrendPoint> out;
  while (s.step()) out.push_back(read_point(s));
  return out;
}

}  // namespace ambdiag::storage
