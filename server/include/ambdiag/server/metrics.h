// The service's own metrics in the Prometheus text exposition format 0.0.4
// (GET /metrics, rest.md "Service"; docs/service.md "Metrics"):
//
//   # HELP ambdiag_http_requests_total HTTP requests by route pattern, method and status.
//   # TYPE ambdiag_http_requests_total counter
//   ambdiag_http_requests_total{route="/api/v1/pumps",method="GET",status="200"} 12
//
// A registry holds families in the order they were registered. A family is
// either owned here (counters, gauges, histograms, one child per label
// values, thread-safe to update from any thread) or collected: a callback
// that produces its samples at each scrape (values kept elsewhere, e.g.
// ingest's atomics, the jobs table, the alarms active by severity).
//
// Names and label names are checked when a family is registered
// (std::logic_error: a programming error); label values are escaped when
// rendered ('\\', '"', newline), so any text may be a label value. Keep
// label values bounded (route patterns, not raw paths).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace ambdiag::server {

enum class MetricType { counter, gauge, histogram };

// Label names and the values of one child, in the same order.
using LabelValues = std::vector<std::string>;

// A monotonic count (Prometheus counter): never decreases.
class Counter {
 public:
  void inc(double by = 1.0) { v_.fetch_add(by, std::memory_order_relaxed); }
  double value() const { return v_.load(std::memory_order_relaxed); }

 private:
  std::atomic<double> v_{0.0};
};

// A value that goes up and down.
class Gauge {
 public:
  void set(double v) { v_.store(v, std::memory_order_relaxed); }
  void add(double by) { v_.fetch_add(by, std::memory_order_relaxed); }
  double value() const { return v_.load(std::memory_order_relaxed); }

 private:
  std::atomic<double> v_{0.0};
};

// Observations counted into buckets with upper bounds `bounds` (ascending,
// finite; +Inf is implied), plus their sum and count.
class Histogram {
 public:
  explicit Histogram(std::vector<double> bounds);
  void observe(double v);
  struct Snapshot {
    std::vector<double> bounds;
    std::vector<std::uint64_t> cumulative;  // per bound, then +Inf (== count)
    double sum = 0;
  };
  Snapshot snapshot() const;

 private:
  std::vector<double> bounds_;
  mutable std::mutex mu_;
  std::vector<std::uint64_t> counts_;  // per bucket, the last one +Inf
  double sum_ = 0;
};

// Seconds from 1 ms to 60 s: HTTP requests and jobs.
std::vector<double> default_seconds_buckets();

// One sample a collected family produces: its label values and its value.
struct MetricSample {
  LabelValues labels;
  double value = 0;
};

// The children of an owned family, created on first use. `with` returns a
// reference that stays valid as long as the registry.
template <class M>
class MetricFamily {
 public:
  M& with(const LabelValues& values);

 private:
  friend class MetricsRegistry;
  explicit MetricFamily(std::size_t n_labels, std::function<std::unique_ptr<M>()> make)
      : n_labels_(n_labels), make_(std::move(make)) {}
  std::size_t n_labels_;
  std::function<std::unique_ptr<M>()> make_;
  mutable std::mutex mu_;
  std::map<LabelValues, std::unique_ptr<M>> children_;
};

class MetricsRegistry {
 public:
  MetricsRegistry();
  ~MetricsRegistry();
  MetricsRegistry(const MetricsRegistry&) = delete;
  MetricsRegistry& operator=(const MetricsRegistry&) = delete;

  // Owned families. A counter's name ends in _total (promtool's rule).
  MetricFamily<Counter>& counter(const std::string& name, const std::string& help,
                                 std::vector<std::string> labels = {});
  MetricFamily<Gauge>& gauge(const std::string& name, const std::string& help,
                             std::vector<std::string> labels = {});
  MetricFamily<Histogram>& histogram(const std::string& name, const std::string& help,
                                     std::vector<std::string> labels, std::vector<double> bounds);
  // A family of counters or gauges whose samples `collect` produces at each
  // scrape; called from a REST worker thread, so it must be thread-safe. If
  // it throws, the family shows no samples that time and
  // ambdiag_metrics_collect_errors_total counts it.
  void collected(const std::string& name, const std::string& help, MetricType type,
                 std::vector<std::string> labels, std::function<std::vector<MetricSample>()> collect);

  // The same for a family of one value without labels.
  void collected_value(const std::string& name, const std::string& help, MetricType type,
                       std::function<double()> value);

  // Every family, text format 0.0.4 (Content-Type text/plain; version=0.0.4).
  std::string render() const;

 private:
  struct Family;
  Family& add(std::unique_ptr<Family> f);
  template <class M>
  MetricFamily<M>& owned(const std::string& name, const std::string& help, MetricType type,
                         std::vector<std::string> labels, std::function<std::unique_ptr<M>()> make);
  mutable std::mutex mu_;
  std::vector<std::unique_ptr<Family>> families_;
  Counter* collect_errors_ = nullptr;
};

// The exposition format's escaping of a label value ('\\', '"', '\n') and a
// HELP text ('\\', '\n'), and its number format ("+Inf", "NaN", shortest
// round-trip decimal otherwise).
std::string escape_label_value(const std::string& v);
std::string escape_help(const std::string& v);
std::string format_metric_value(double v);

template <class M>
M& MetricFamily<M>::with(const LabelValues& values) {
  if (values.size() != n_labels_) throw std::logic_error("metric: wrong number of label values");
  std::lock_guard l(mu_);
  auto& slot = children_[values];
  if (!slot) slot = make_();
  return *slot;
}

}  // namespace ambdiag::server
