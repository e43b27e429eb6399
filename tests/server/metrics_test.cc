// MetricsRegistry: the text exposition format 0.0.4 it renders, the names
// it refuses, and counts that stay exact under concurrent updates.
#include "ambdiag/server/metrics.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <thread>

namespace ambdiag::server {
namespace {

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(Metrics, CountersAndGaugesRenderWithHelpTypeAndEscapedLabels) {
  MetricsRegistry r;
  auto& c = r.counter("x_requests_total", "Requests\nby path \\ kind.", {"path"});
  c.with({"a\"b\\c\nd"}).inc(2);
  c.with({"plain"}).inc();
  r.gauge("x_temperature_celsius", "A gauge.").with({}).set(-1.5);
  const std::string text = r.render();
  EXPECT_TRUE(contains(text, "# HELP x_requests_total Requests\\nby path \\\\ kind.\n")) << text;
  EXPECT_TRUE(contains(text, "# TYPE x_requests_total counter\n")) << text;
  EXPECT_TRUE(contains(text, "x_requests_total{path=\"a\\\"b\\\\c\\nd\"} 2\n")) << text;
  EXPECT_TRUE(contains(text, "x_requests_total{path=\"plain\"} 1\n")) << text;
  EXPECT_TRUE(contains(text, "# TYPE x_temperature_celsius gauge\nx_temperature_celsius -1.5\n")) << text;
}

TEST(Metrics, AHistogramHasCumulativeBucketsUpToInfWithSumAndCount) {
  MetricsRegistry r;
  auto& h = r.histogram("x_duration_seconds", "Durations.", {"kind"}, {0.1, 1});
  h.with({"k"}).observe(0.05);
  h.with({"k"}).observe(0.1);  // le is inclusive
  h.with({"k"}).observe(0.5);
  h.with({"k"}).observe(7);
  const std::string text = r.render();
  EXPECT_TRUE(contains(text, "x_duration_seconds_bucket{kind=\"k\",le=\"0.1\"} 2\n")) << text;
  EXPECT_TRUE(contains(text, "x_duration_seconds_bucket{kind=\"k\",le=\"1\"} 3\n")) << text;
  EXPECT_TRUE(contains(text, "x_duration_seconds_bucket{kind=\"k\",le=\"+Inf\"} 4\n")) << text;
  EXPECT_TRUE(contains(text, "x_duration_seconds_sum{kind=\"k\"} 7.65\n")) << text;
  EXPECT_TRUE(contains(text, "x_duration_seconds_count{kind=\"k\"} 4\n")) << text;
}

TEST(Metrics, ACollectedFamilyIsReadAtEachScrapeAndOneThatThrowsShowsNoSamples) {
  MetricsRegistry r;
  double v = 1;
  bool fail = false;
  r.collected("x_alarms_active", "Alarms.", MetricType::gauge, {"severity"}, [&] {
    if (fail) throw std::runtime_error("database gone");
    return std::vector<MetricSample>{{{"high"}, v}, {{"low"}, 2 * v}};
  });
  EXPECT_TRUE(
      contains(r.render(), "x_alarms_active{severity=\"high\"} 1\nx_alarms_active{severity=\"low\"} 2\n"));
  v = 3;
  EXPECT_TRUE(contains(r.render(), "x_alarms_active{severity=\"high\"} 3\n"));
  fail = true;
  const std::string text = r.render();
  EXPECT_FALSE(contains(text, "x_alarms_active{")) << text;
  EXPECT_TRUE(contains(text, "# TYPE x_alarms_active gauge\n")) << text;
  // Counted at this scrape, after its own line was written: shown at the next.
  EXPECT_TRUE(contains(r.render(), "ambdiag_metrics_collect_errors_total 1\n"));
}

TEST(Metrics, BadNamesDuplicatesAndCountersWithoutTotalAreRefused) {
  MetricsRegistry r;
  EXPECT_THROW(r.counter("x_requests", "no _total"), std::logic_error);
  EXPECT_THROW(r.gauge("x_open_total", "a gauge with _total"), std::logic_error);
  EXPECT_THROW(r.gauge("1x", "starts with a digit"), std::logic_error);
  EXPECT_THROW(r.gauge("x-y", "dash"), std::logic_error);
  EXPECT_THROW(r.gauge("x_ok", "bad label", {"le-vel"}), std::logic_error);
  EXPECT_THROW(r.histogram("x_h_seconds", "le is reserved", {"le"}, {1}), std::logic_error);
  EXPECT_THROW(r.histogram("x_h_seconds", "bounds not ascending", {}, {1, 0.5}), std::logic_error);
  r.gauge("x_ok", "fine");
  EXPECT_THROW(r.gauge("x_ok", "twice"), std::logic_error);
  EXPECT_THROW(r.counter("y_total", "one label", {"a"}).with({"1", "2"}), std::logic_error);
}

TEST(Metrics, NumbersUseThePrometheusSpellings) {
  EXPECT_EQ(format_metric_value(1.0 / 0.0), "+Inf");
  EXPECT_EQ(format_metric_value(-1.0 / 0.0), "-Inf");
  EXPECT_EQ(format_metric_value(0.0 / 0.0), "NaN");
  EXPECT_EQ(format_metric_value(0.005), "0.005");
  EXPECT_EQ(format_metric_value(1234567), "1234567");
}

TEST(Metrics, ConcurrentIncrementsFromManyThreadsAreAllCounted) {
  MetricsRegistry r;
  auto& c = r.counter("x_total", "Count.", {"t"});
  auto& h = r.histogram("x_seconds", "H.", {}, {1});
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      for (int i = 0; i < 20000; ++i) {
        c.with({std::to_string(i % 3)}).inc();
        h.with({}).observe(t);
      }
    });
  for (auto& t : threads) t.join();
  double total = 0;
  for (const char* k : {"0", "1", "2"}) total += c.with({k}).value();
  EXPECT_EQ(total, 80000);
  EXPECT_EQ(h.with({}).snapshot().cumulative.back(), 80000u);
}

}  // namespace
}  // namespace ambdiag::server
