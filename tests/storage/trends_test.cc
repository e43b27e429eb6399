// Trend series (schema v5): points kept with the analysis job's result in
// one transaction, replaced by a newer analysis of the run, filled in for a
// file upgraded from v4, queried by range as points, pages or min/max
// buckets; monitoring values read as series.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"
#include "sqlite_raw.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

using ambdiag::testing::run_json_text;

std::string db_path() { return (ambdiag::testing::scratch_dir() / "h.db").string(); }

class HistorianTrendsTest : public ambdiag::testing::BackendTest {};
AMBDIAG_ON_BOTH_BACKENDS(HistorianTrendsTest);

constexpr std::int64_t kHourNs = 3'600'000'000'000;
const std::int64_t kT0 = ns_from_utc("2026-01-01T00:00:00Z", "t0");

// A run of pump P-1 started at kT0 + i hours.
std::string add_run(Historian& h, int i, const std::string& pump_id = "P-1") {
  const std::string run_id = pump_id + "/r" + std::to_string(i);
  auto j = nlohmann::json::parse(run_json_text(run_id, 1, pump_id));
  j["started_at"] = utc_from_ns(kT0 + i * kHourNs);
  h.begin_run(run_header_from_json(j.dump()));
  return run_id;
}

std::vector<SeriesValue> values(double ratio, double f_hz = 50.0) {
  return {{"detection.ratio", "1", ratio, std::nullopt}, {"mode.m1.f_hz", "Hz", f_hz, 0.1}};
}

// Claims the job with this key and stores the result with its series.
bool finish(Historian& h, const JobKey& key, const std::optional<std::vector<SeriesValue>>& series,
            const std::string& result = "{}") {
  const auto [id, created] = h.enqueue_job(key);
  const auto job = h.claim_job("w");
  EXPECT_TRUE(job && job->job_id == id);
  return h.finish_job(id, job->attempts, result, {}, series);
}

JobKey analysis(const std::string& run_id, int model = 1, int reference = 0) {
  return {"analysis", "P-1", run_id, model, reference};
}

std::vector<TrendPoint> all_points(Historian& h, const std::string& name) {
  const auto t = h.query_trend("P-1", name, TrendQuery{});
  EXPECT_TRUE(t);
  return t ? t->points : std::vector<TrendPoint>{};
}

TEST_P(HistorianTrendsTest, AnAnalysisResultBringsItsPointsAtTheRunsStart) {
  auto h = Historian::open(location());
  const auto r0 = add_run(h, 0), r1 = add_run(h, 1);
  ASSERT_TRUE(finish(h, analysis(r1), values(0.5, 51.0)));
  ASSERT_TRUE(finish(h, analysis(r0), values(0.25, 50.0)));
  const auto series = h.list_series("P-1");
  ASSERT_EQ(series.size(), 2u);
  EXPECT_EQ(series[0].name, "detection.ratio");
  EXPECT_EQ(series[1].name, "mode.m1.f_hz");
  EXPECT_EQ(series[1].unit, "Hz");
  const auto p = all_points(h, "mode.m1.f_hz");
  ASSERT_EQ(p.size(), 2u);  // oldest first, whatever the order analysed
  EXPECT_EQ(p[0].run_id, r0);
  EXPECT_EQ(p[0].time_ns, kT0);
  EXPECT_EQ(p[1].time_ns, kT0 + kHourNs);
  EXPECT_DOUBLE_EQ(p[1].value, 51.0);
  ASSERT_TRUE(p[1].sd);
  EXPECT_DOUBLE_EQ(*p[1].sd, 0.1);
  EXPECT_FALSE(all_points(h, "detection.ratio")[0].sd);
  EXPECT_FALSE(h.query_trend("P-1", "no.such", TrendQuery{}));
  EXPECT_FALSE(h.query_trend("P-2", "detection.ratio", TrendQuery{}));
}

TEST_P(HistorianTrendsTest, PointsAndResultAreOneTransaction) {
  const auto path = location();
  auto h = Historian::open(path);
  const auto r0 = add_run(h, 0);
  const auto [id, created] = h.enqueue_job(analysis(r0));
  const auto job = h.claim_job("w");
  ASSERT_TRUE(job);
  // A bad value refuses the whole finish: no result, no point.
  auto bad = values(0.5);
  bad.push_back({"fit.nrmse", "1", std::nan(""), std::nullopt});
  EXPECT_THROW(h.finish_job(id, job->attempts, R"({"x": 1})", {}, bad), InputError);
  EXPECT_EQ(h.find_job(id)->status, JobStatus::running);
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM series_points"), 0);
  // An attempt that no longer holds the job stores neither.
  EXPECT_FALSE(h.finish_job(id, job->attempts + 1, "{}", {}, values(0.5)));
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM series_points"), 0);
  // Inside a batch that rolls back, both go.
  {
    auto batch = h.write_batch();
    EXPECT_TRUE(h.finish_job(id, job->attempts, "{}", {}, values(0.5)));
  }
  EXPECT_EQ(h.find_job(id)->status, JobStatus::running);
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM series_points"), 0);
  EXPECT_TRUE(h.finish_job(id, job->attempts, "{}", {}, values(0.5)));
  EXPECT_EQ(h.find_job(id)->status, JobStatus::done);
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM series_points"), 2);
}

TEST_P(HistorianTrendsTest, ANewerAnalysisOfTheRunReplacesItsPointsAndAnOlderOneDoesNot) {
  auto h = Historian::open(location());
  const auto r0 = add_run(h, 0);
  ASSERT_TRUE(finish(h, analysis(r0, 1, 0), values(0.5, 50.0)));
  // Reference version 1: a new job for the same run; its series differ.
  ASSERT_TRUE(finish(h, analysis(r0, 1, 1), {{{"detection.ratio", "1", 2.0, std::nullopt}}}));
  auto p = all_points(h, "detection.ratio");
  ASSERT_EQ(p.size(), 1u);  // one point per run and series
  EXPECT_DOUBLE_EQ(p[0].value, 2.0);
  EXPECT_TRUE(all_points(h, "mode.m1.f_hz").empty());  // the newest analysis gave none
  // An older job (created before) that finishes late does not win.
  const auto [old_id, made] = h.enqueue_job(analysis(r0, 0, 0));
  ASSERT_TRUE(made);
  const auto newest = h.enqueue_job(analysis(r0, 2, 1)).first;
  ASSERT_LT(old_id, newest);
  const auto a = h.claim_job("w"), b = h.claim_job("w");
  ASSERT_TRUE(a && b);
  ASSERT_TRUE(h.finish_job(newest, (a->job_id == newest ? a : b)->attempts, "{}", {}, values(3.0)));
  ASSERT_TRUE(h.finish_job(old_id, (a->job_id == old_id ? a : b)->attempts, "{}", {}, values(9.0)));
  p = all_points(h, "detection.ratio");
  ASSERT_EQ(p.size(), 1u);
  EXPECT_DOUBLE_EQ(p[0].value, 3.0);
}

TEST_P(HistorianTrendsTest, OnlyAnalysisJobsFeedTheSeries) {
  auto h = Historian::open(location());
  const auto r0 = add_run(h, 0);
  ASSERT_TRUE(finish(h, {"explain", "P-1", r0, 1, 0}, values(0.5)));
  ASSERT_TRUE(finish(h, {"reference", "P-1", "", 1, 1}, values(0.5)));
  ASSERT_TRUE(finish(h, analysis("P-1/not-held"), values(0.5)));  // no run: no time for it
  ASSERT_TRUE(finish(h, analysis(r0), std::nullopt));
  EXPECT_TRUE(h.list_series("P-1").empty());
}

TEST(HistorianTrends, AVersion4FileGetsItsTableAndItsPointsFilledIn) {
  const auto path = db_path();
  {
    auto h = Historian::open(path);
    const auto r0 = add_run(h, 0), r1 = add_run(h, 1);
    ASSERT_TRUE(finish(h, analysis(r0, 1, 0), std::nullopt, R"({"ratio": 0.1})"));
    ASSERT_TRUE(finish(h, analysis(r0, 1, 1), std::nullopt, R"({"ratio": 0.2})"));  // the newest of r0
    ASSERT_TRUE(finish(h, analysis(r1, 1, 1), std::nullopt, R"({"ratio": 0.3})"));
    ASSERT_TRUE(finish(h, {"explain", "P-1", r1, 1, 0}, std::nullopt, R"({"ratio": 9})"));
  }
  downgrade_schema(path, 4);
  EXPECT_THROW(Historian::open(path, Historian::Mode::read), InputError);  // readers do not migrate
  auto h = Historian::open(path);
  EXPECT_EQ(raw_query_int(path, "PRAGMA user_version"), Historian::schema_version());
  std::vector<std::string> seen;
  const auto series_of = [&](const std::string& result) {
    seen.push_back(result);
    const double r = nlohmann::json::parse(result)["ratio"].get<double>();
    return std::vector<SeriesValue>{{"detection.ratio", "1", r, std::nullopt}};
  };
  EXPECT_EQ(h.backfill_series(series_of), 2);
  EXPECT_EQ(seen.size(), 2u);  // the older analysis of r0 and the explain job are not read
  const auto p = all_points(h, "detection.ratio");
  ASSERT_EQ(p.size(), 2u);
  EXPECT_DOUBLE_EQ(p[0].value, 0.2);
  EXPECT_DOUBLE_EQ(p[1].value, 0.3);
  EXPECT_EQ(h.backfill_series(series_of), 0);  // done once
  EXPECT_EQ(seen.size(), 2u);
}

TEST_P(HistorianTrendsTest, RangeEdgesAreInclusive) {
  auto h = Historian::open(location());
  for (int i = 0; i < 10; ++i) ASSERT_TRUE(finish(h, analysis(add_run(h, i)), values(i)));
  TrendQuery q;
  q.from_ns = kT0 + 2 * kHourNs;
  q.to_ns = kT0 + 5 * kHourNs;
  auto t = h.query_trend("P-1", "detection.ratio", q);
  ASSERT_TRUE(t);
  ASSERT_EQ(t->count, 4);
  ASSERT_EQ(t->points.size(), 4u);
  EXPECT_DOUBLE_EQ(t->points.front().value, 2.0);
  EXPECT_DOUBLE_EQ(t->points.back().value, 5.0);
  q.from_ns = q.to_ns = kT0 + 5 * kHourNs;  // a single instant
  EXPECT_EQ(h.query_trend("P-1", "detection.ratio", q)->points.size(), 1u);
  q.from_ns = q.to_ns = kT0 + 5 * kHourNs + 1;
  EXPECT_EQ(h.query_trend("P-1", "detection.ratio", q)->count, 0);
  q.from_ns = kT0 + kHourNs;
  q.to_ns = kT0;
  EXPECT_THROW(h.query_trend("P-1", "detection.ratio", q), InputError);
  q = TrendQuery{};
  q.max_points = 0;
  EXPECT_THROW(h.query_trend("P-1", "detection.ratio", q), InputError);
}

TEST_P(HistorianTrendsTest, BucketsKeepEveryPeakAndCountEveryPoint) {
  auto h = Historian::open(location());
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<double> v;
  {
    auto batch = h.write_batch();
    for (int i = 0; i < 3000; ++i) {
      v.push_back(noise(rng) + (i == 1234 ? 40.0 : 0.0) - (i == 2999 ? 30.0 : 0.0));
      ASSERT_TRUE(finish(h, analysis(add_run(h, i)), values(v.back())));
    }
    batch.commit();
  }
  TrendQuery q;
  q.max_points = 97;
  const auto t = h.query_trend("P-1", "detection.ratio", q);
  ASSERT_TRUE(t);
  EXPECT_EQ(t->count, 3000);
  EXPECT_TRUE(t->points.empty());
  ASSERT_FALSE(t->buckets.empty());
  EXPECT_LE(t->buckets.size(), 97u);
  EXPECT_GE(t->buckets.size(), 90u);
  std::int64_t n = 0;
  double lo = 1e300, hi = -1e300;
  for (size_t i = 0; i < t->buckets.size(); ++i) {
    const auto& b = t->buckets[i];
    n += b.count;
    lo = std::min(lo, b.min);
    hi = std::max(hi, b.max);
    EXPECT_EQ((b.time_ns - kT0) % t->bucket_ns, 0);  // equal buckets from the first point on
    // Each bucket's points are those of runs in [time, time + width).
    const auto first = static_cast<size_t>((b.time_ns - kT0 + kHourNs - 1) / kHourNs);
    EXPECT_DOUBLE_EQ(b.first, v[first]);
    EXPECT_DOUBLE_EQ(b.last, v[first + static_cast<size_t>(b.count) - 1]);
    EXPECT_DOUBLE_EQ(b.max, *std::max_element(v.begin() + static_cast<long>(first), v.begin() + static_cast<long>(first + b.count)));
  }
  EXPECT_EQ(n, 3000);
  EXPECT_DOUBLE_EQ(hi, *std::max_element(v.begin(), v.end()));  // the spike at 1234
  EXPECT_DOUBLE_EQ(lo, *std::min_element(v.begin(), v.end()));  // the dip at the very end
  EXPECT_DOUBLE_EQ(t->buckets.back().last, v.back());
}

TEST_P(HistorianTrendsTest, RawPagesGoOnWhereTheLastStoppedWithoutRepeats) {
  auto h = Historian::open(location());
  for (int i = 0; i < 25; ++i) ASSERT_TRUE(finish(h, analysis(add_run(h, i)), values(i)));
  TrendQuery q;
  q.raw = true;
  q.max_points = 10;
  std::vector<double> got;
  int pages = 0;
  for (;;) {
    const auto t = h.query_trend("P-1", "detection.ratio", q);
    ASSERT_TRUE(t);
    ++pages;
    for (const auto& p : t->points) got.push_back(p.value);
    if (!t->truncated) break;
    ASSERT_TRUE(t->next_from_ns);
    q.from_ns = *t->next_from_ns;
  }
  EXPECT_EQ(pages, 3);
  ASSERT_EQ(got.size(), 25u);
  for (int i = 0; i < 25; ++i) EXPECT_DOUBLE_EQ(got[static_cast<size_t>(i)], i);
}

TEST_P(HistorianTrendsTest, MonitoringValuesAreSeriesReadFromTheSnapshots) {
  auto h = Historian::open(location());
  EXPECT_TRUE(h.list_series("P-1").empty());
  std::vector<MonitoringSnapshot> snaps;
  for (int i = 0; i < 5; ++i) {
    MonitoringSnapshot s;
    s.pump_id = "P-1";
    s.time_ns = kT0 + i * 1'000'000'000LL;
    s.speed_rpm = 3000 + i;
    s.orbit_major_m = {1e-6 * (i + 1), 2e-6};
    s.force_1x_amp_n = {1.0, 2.0, 3.0, 4.0 + i};
    snaps.push_back(s);
  }
  h.put_monitoring(snaps);
  const auto series = h.list_series("P-1");
  EXPECT_EQ(series.size(), 25u);
  const auto has = [&](const std::string& name, const std::string& unit) {
    return std::ranges::any_of(series, [&](const SeriesInfo& s) { return s.name == name && s.unit == unit; });
  };
  EXPECT_TRUE(has("monitoring.speed_rpm", "rpm"));
  EXPECT_TRUE(has("monitoring.orbit_major_m.a", "m"));
  EXPECT_TRUE(has("monitoring.force_1x_phase_rad.by", "rad"));
  auto p = all_points(h, "monitoring.force_1x_amp_n.by");
  ASSERT_EQ(p.size(), 5u);
  EXPECT_DOUBLE_EQ(p[4].value, 8.0);
  EXPECT_TRUE(p[4].run_id.empty());
  EXPECT_FALSE(p[4].sd);
  TrendQuery q;
  q.max_points = 2;
  const auto t = h.query_trend("P-1", "monitoring.orbit_major_m.a", q);
  ASSERT_TRUE(t);
  ASSERT_EQ(t->buckets.size(), 2u);
  EXPECT_DOUBLE_EQ(t->buckets[0].min, 1e-6);
  EXPECT_DOUBLE_EQ(t->buckets[1].max, 5e-6);
  EXPECT_FALSE(h.query_trend("P-2", "monitoring.speed_rpm", TrendQuery{}));  // no snapshots
  EXPECT_FALSE(h.query_trend("P-1", "monitoring.orbit_major_m", TrendQuery{}));
}

TEST_P(HistorianTrendsTest, PointsOfGivenRunsForTheReferenceBand) {
  auto h = Historian::open(location());
  std::vector<std::string> runs;
  for (int i = 0; i < 6; ++i) {
    runs.push_back(add_run(h, i));
    ASSERT_TRUE(finish(h, analysis(runs.back()), values(0.1 * i)));
  }
  const auto p = h.run_points("P-1", "detection.ratio", {runs[4], runs[1], "P-1/unknown"});
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p[0].run_id, runs[1]);
  EXPECT_DOUBLE_EQ(p[1].value, 0.4);
  EXPECT_TRUE(h.run_points("P-1", "no.such", runs).empty());
}

}  // namespace
}  // namespace ambdiag::storage
