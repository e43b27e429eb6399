#include "ambdiag/server/metrics.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <type_traits>

namespace ambdiag::server {

namespace {

bool valid_name(const std::string& s, bool colon) {
  if (s.empty()) return false;
  for (size_t i = 0; i < s.size(); ++i) {
    const char c = s[i];
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' || (colon && c == ':') ||
                    (i > 0 && c >= '0' && c <= '9');
    if (!ok) return false;
  }
  return true;
}

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

const char* type_name(MetricType t) {
  switch (t) {
    case MetricType::counter:
      return "counter";
    case MetricType::gauge:
      return "gauge";
    case MetricType::histogram:
      return "histogram";
  }
  return "untyped";
}

// name{a="x",b="y"} value
void sample_line(std::string& out, const std::string& name, const std::vector<std::string>& names,
                 const LabelValues& values, double v, const std::string& extra_name = {},
                 const std::string& extra_value = {}) {
  out += name;
  if (!names.empty() || !extra_name.empty()) {
    out += '{';
    bool first = true;
    const auto label = [&](const std::string& n, const std::string& x) {
      if (!first) out += ',';
      first = false;
      out += n + "=\"" + escape_label_value(x) + '"';
    };
    for (size_t i = 0; i < names.size(); ++i) label(names[i], values[i]);
    if (!extra_name.empty()) label(extra_name, extra_value);
    out += '}';
  }
  out += ' ' + format_metric_value(v) + '\n';
}

}  // namespace

namespace {

// Backslash and newline always; the double quote only inside a label value.
std::string escape(const std::string& v, bool quote) {
  std::string out;
  out.reserve(v.size());
  for (const char c : v) {
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    if (c == '\\' || (quote && c == '"')) out += '\\';
    out += c;
  }
  return out;
}

}  // namespace

std::string escape_label_value(const std::string& v) { return escape(v, true); }
std::string escape_help(const std::string& v) { return escape(v, false); }

std::string format_metric_value(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

Histogram::Histogram(std::vector<double> bounds)
    : bounds_(std::move(bounds)), counts_(bounds_.size() + 1, 0) {
  for (size_t i = 0; i < bounds_.size(); ++i)
    if (!std::isfinite(bounds_[i]) || (i > 0 && bounds_[i] <= bounds_[i - 1]))
      throw std::logic_error("histogram bounds must be finite and ascending");
}

void Histogram::observe(double v) {
  const size_t i = static_cast<size_t>(std::lower_bound(bounds_.begin(), bounds_.end(), v) - bounds_.begin());
  std::lock_guard l(mu_);
  ++counts_[i];  // the first bucket whose bound is >= v ("le"); NaN lands in +Inf
  sum_ += v;
}

Histogram::Snapshot Histogram::snapshot() const {
  Snapshot s;
  s.bounds = bounds_;
  std::lock_guard l(mu_);
  std::uint64_t acc = 0;
  for (const auto c : counts_) s.cumulative.push_back(acc += c);
  s.sum = sum_;
  return s;
}

std::vector<double> default_seconds_buckets() {
  return {0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30, 60};
}

struct MetricsRegistry::Family {
  std::string name, help;
  MetricType type;
  std::vector<std::string> labels;
  std::unique_ptr<MetricFamily<Counter>> counters;
  std::unique_ptr<MetricFamily<Gauge>> gauges;
  std::unique_ptr<MetricFamily<Histogram>> histograms;
  std::function<std::vector<MetricSample>()> collect;
};

MetricsRegistry::MetricsRegistry() {
  collect_errors_ = &counter("ambdiag_metrics_collect_errors_total",
                             "Scrapes at which a collected family could not be read (it showed no samples).")
                         .with({});
}

MetricsRegistry::~MetricsRegistry() = default;

// Checks the names and registers a family built complete, so a scrape
// never sees one half made.
MetricsRegistry::Family& MetricsRegistry::add(std::unique_ptr<Family> f) {
  const std::string& name = f->name;
  if (!valid_name(name, true))
    throw std::logic_error("metric name '" + name + "' is not [a-zA-Z_:][a-zA-Z0-9_:]*");
  if ((f->type == MetricType::counter) != ends_with(name, "_total"))
    throw std::logic_error("metric '" + name + "': counters, and only counters, end in _total");
  for (const auto& l : f->labels)
    if (!valid_name(l, false) || l.rfind("__", 0) == 0 || (f->type == MetricType::histogram && l == "le"))
      throw std::logic_error("metric '" + name + "': bad label name '" + l + "'");
  std::lock_guard lock(mu_);
  for (const auto& o : families_)
    if (o->name == name) throw std::logic_error("metric '" + name + "' registered twice");
  families_.push_back(std::move(f));
  return *families_.back();
}

template <class M>
MetricFamily<M>& MetricsRegistry::owned(const std::string& name, const std::string& help, MetricType type,
                                        std::vector<std::string> labels,
                                        std::function<std::unique_ptr<M>()> make) {
  auto f = std::make_unique<Family>(Family{name, help, type, std::move(labels), {}, {}, {}, {}});
  auto* family = new MetricFamily<M>(f->labels.size(), std::move(make));
  if constexpr (std::is_same_v<M, Counter>)
    f->counters.reset(family);
  else if constexpr (std::is_same_v<M, Gauge>)
    f->gauges.reset(family);
  else
    f->histograms.reset(family);
  add(std::move(f));
  return *family;
}

MetricFamily<Counter>& MetricsRegistry::counter(const std::string& name, const std::string& help,
                                                std::vector<std::string> labels) {
  return owned<Counter>(name, help, MetricType::counter, std::move(labels),
                        [] { return std::make_unique<Counter>(); });
}

MetricFamily<Gauge>& MetricsRegistry::gauge(const std::string& name, const std::string& help,
                                            std::vector<std::string> labels) {
  return owned<Gauge>(name, help, MetricType::gauge, std::move(labels),
                      [] { return std::make_unique<Gauge>(); });
}

MetricFamily<Histogram>& MetricsRegistry::histogram(const std::string& name, const std::string& help,
                                                    std::vector<std::string> labels,
                                                    std::vector<double> bounds) {
  Histogram check(bounds);  // refuses bad bounds before anything is registered
  return owned<Histogram>(name, help, MetricType::histogram, std::move(labels),
                          [bounds] { return std::make_unique<Histogram>(bounds); });
}

void MetricsRegistry::collected(const std::string& name, const std::string& help, MetricType type,
                                std::vector<std::string> labels,
                                std::function<std::vector<MetricSample>()> collect) {
  if (type == MetricType::histogram)
    throw std::logic_error("metric '" + name + "': a collected family is a counter or a gauge");
  if (!collect) throw std::logic_error("metric '" + name + "': no collector");
  add(std::make_unique<Family>(Family{name, help, type, std::move(labels), {}, {}, {}, std::move(collect)}));
}

void MetricsRegistry::collected_value(const std::string& name, const std::string& help, MetricType type,
                                      std::function<double()> value) {
  if (!value) throw std::logic_error("metric '" + name + "': no collector");
  collected(name, help, type, {}, [value = std::move(value)] {
    return std::vector<MetricSample>{{{}, value()}};
  });
}

std::string MetricsRegistry::render() const {
  std::vector<const Family*> families;
  {
    std::lock_guard l(mu_);
    for (const auto& f : families_) families.push_back(f.get());
  }
  std::string out;
  for (const Family* f : families) {
    std::string body;
    if (f->collect) {
      try {
        auto samples = f->collect();
        // One line per label values: the format forbids repeating a series.
        std::sort(samples.begin(), samples.end(),
                  [](const auto& a, const auto& b) { return a.labels < b.labels; });
        for (size_t i = 0; i < samples.size(); ++i) {
          if (samples[i].labels.size() != f->labels.size())
            throw std::logic_error("wrong number of label values");
          if (i > 0 && samples[i].labels == samples[i - 1].labels) continue;
          sample_line(body, f->name, f->labels, samples[i].labels, samples[i].value);
        }
      } catch (const std::exception&) {
        body.clear();
        collect_errors_->inc();
      }
    } else if (f->counters) {
      std::lock_guard l(f->counters->mu_);
      for (const auto& [values, c] : f->counters->children_)
        sample_line(body, f->name, f->labels, values, c->value());
    } else if (f->gauges) {
      std::lock_guard l(f->gauges->mu_);
      for (const auto& [values, g] : f->gauges->children_)
        sample_line(body, f->name, f->labels, values, g->value());
    } else if (f->histograms) {
      std::lock_guard l(f->histograms->mu_);
      for (const auto& [values, h] : f->histograms->children_) {
        const auto s = h->snapshot();
        for (size_t i = 0; i < s.cumulative.size(); ++i)
          sample_line(body, f->name + "_bucket", f->labels, values, static_cast<double>(s.cumulative[i]),
                      "le", i < s.bounds.size() ? format_metric_value(s.bounds[i]) : "+Inf");
        sample_line(body, f->name + "_sum", f->labels, values, s.sum);
        sample_line(body, f->name + "_count", f->labels, values, static_cast<double>(s.cumulative.back()));
      }
    }
    out += "# HELP " + f->name + ' ' + escape_help(f->help) + '\n';
    out += "# TYPE " + f->name + ' ' + type_name(f->type) + '\n';
    out += body;
  }
  return out;
}

}  // namespace ambdiag::server
