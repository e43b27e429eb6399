#include "ambdiag/server/retention_service.h"

#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <thread>

#include "ambdiag/core/error.h"
#include "ambdiag/server/analysis_service.h"
#include "ambdiag/server/metrics.h"

namespace ambdiag::server {

using nlohmann::json;

storage::RetentionPolicy retention_defaults_from_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("--retention " + path + ": cannot be read");
  json j;
  try {
    j = json::parse(in);
  } catch (const json::exception& e) {
    throw InputError("--retention " + path + ": not JSON: " + e.what());
  }
  return storage::retention_policy_from_json(j, storage::RetentionPolicy{}, "--retention " + path);
}

std::optional<json> retention_view(storage::Historian& h, const std::string& pump_id,
                                   const storage::RetentionPolicy& defaults) {
  auto snap = h.snapshot();
  if (!h.find_pump(pump_id)) return std::nullopt;
  const auto own = h.find_retention_policy(pump_id);
  json j = {{"pump_id", pump_id},
            {"policy", to_json(h.effective_retention_policy(pump_id, defaults))},
            {"source", own ? "pump" : "defaults"},
            {"override", own ? json::parse(own->policy_json) : json::object()},
            {"defaults", to_json(defaults)}};
  if (own) {
    j["version"] = own->version;
    j["created_at"] = own->created_at;
    j["created_by"] = own->created_by;
  }
  const auto u = h.retention_usage(pump_id);
  j["usage"] = {{"runs_with_samples", u.runs_with_samples},
                {"samples_bytes_held", u.samples_bytes_held},
                {"runs_samples_dropped", u.runs_samples_dropped},
                {"samples_bytes_dropped", u.samples_bytes_dropped},
                {"runs_frf_dropped", u.runs_frf_dropped},
                {"frf_bytes_dropped", u.frf_bytes_dropped}};
  return j;
}

namespace {

std::string holder_name() {
  char host[256] = {};
  ::gethostname(host, sizeof host - 1);
  return "ambdiag serve " + std::to_string(::getpid()) + "@" + host;
}

}  // namespace

struct RetentionService::Impl {
  RetentionOptions opt;
  const std::string holder = holder_name();
  std::mutex put_mu;  // one PUT at a time on `writer`
  std::optional<storage::Historian> writer;
  std::mutex sweep_mu;  // one sweep at a time in this process
  mutable std::mutex report_mu;
  json last = nullptr;
  std::atomic<bool> stopping{false};
  std::mutex wake_mu;
  std::condition_variable wake;
  std::thread thread;
  // Metrics (null without a registry).
  MetricFamily<Counter>* dropped_bytes = nullptr;
  MetricFamily<Counter>* dropped_runs = nullptr;
  Counter* monitoring_rows = nullptr;
  MetricFamily<Counter>* sweeps = nullptr;
  Gauge* last_time = nullptr;
  Gauge* last_duration = nullptr;
  Gauge* longest_tx = nullptr;

  explicit Impl(RetentionOptions o) : opt(std::move(o)) {
    if (!opt.metrics) return;
    auto& m = *opt.metrics;
    dropped_bytes = &m.counter("ambdiag_retention_dropped_bytes_total",
                               "Bytes the retention sweeps dropped, by what: samples (runs' raw samples) or frf (the "
                               "analyses' files).",
                               {"what"});
    dropped_runs = &m.counter("ambdiag_retention_dropped_runs_total",
                              "Runs whose samples (or analyses' files) the retention sweeps dropped, by what.", {"what"});
    monitoring_rows = &m.counter("ambdiag_retention_monitoring_dropped_total",
                                 "Monitoring snapshots the retention sweeps dropped.")
                           .with({});
    sweeps = &m.counter("ambdiag_retention_sweeps_total",
                        "Retention sweeps by outcome: done, skipped (another sweep held the lease) or failed.", {"outcome"});
    last_time = &m.gauge("ambdiag_retention_last_sweep_timestamp_seconds",
                         "When the last retention sweep of this server ended (Unix time; 0: none yet).")
                     .with({});
    last_duration = &m.gauge("ambdiag_retention_last_sweep_duration_seconds", "How long the last retention sweep took.").with({});
    longest_tx = &m.gauge("ambdiag_retention_last_sweep_longest_transaction_seconds",
                          "The longest write transaction of the last retention sweep: the longest ingest could wait for it.")
                      .with({});
    for (const char* what : {"samples", "frf"}) {  // shown from 0
      dropped_bytes->with({what});
      dropped_runs->with({what});
    }
    for (const char* outcome : {"done", "skipped", "failed"}) sweeps->with({outcome});
  }

  storage::SweepReport sweep() {
    std::lock_guard l(sweep_mu);
    storage::SweepOptions so;
    so.holder = holder;
    so.stop = [this] { return stopping.load(); };
    storage::SweepReport r;
    try {
      auto h = storage::Historian::open(opt.db_path, storage::Historian::Mode::write);
      r = h.sweep_retention(opt.defaults, so);
    } catch (const std::exception& e) {
      if (sweeps) sweeps->with({"failed"}).inc();
      std::fprintf(stderr, "ambdiag serve: retention sweep failed: %s\n", e.what());
      std::lock_guard rl(report_mu);
      last = {{"error", e.what()}};
      return r;
    }
    account(r);
    return r;
  }

  void account(const storage::SweepReport& r) {
    if (sweeps) {
      sweeps->with({r.skipped.empty() ? "done" : "skipped"}).inc();
      dropped_bytes->with({"samples"}).inc(static_cast<double>(r.samples_bytes));
      dropped_bytes->with({"frf"}).inc(static_cast<double>(r.frf_bytes));
      dropped_runs->with({"samples"}).inc(static_cast<double>(r.samples_runs));
      dropped_runs->with({"frf"}).inc(static_cast<double>(r.frf_runs));
      monitoring_rows->inc(static_cast<double>(r.monitoring_rows));
      last_time->set(std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count());
      last_duration->set(r.seconds);
      longest_tx->set(r.longest_transaction_s);
    }
    if (opt.verbose && (r.samples_runs || r.frf_runs || r.monitoring_rows || !r.errors.empty()))
      std::fprintf(stderr,
                   "ambdiag serve: retention: %lld runs' samples (%.1f MB), %lld runs' FRFs (%.1f MB), %lld monitoring "
                   "snapshots dropped in %.2f s (longest transaction %.3f s)%s\n",
                   static_cast<long long>(r.samples_runs), static_cast<double>(r.samples_bytes) / 1e6,
                   static_cast<long long>(r.frf_runs), static_cast<double>(r.frf_bytes) / 1e6,
                   static_cast<long long>(r.monitoring_rows), r.seconds, r.longest_transaction_s,
                   r.errors.empty() ? "" : ("; " + r.errors.front()).c_str());
    std::lock_guard l(report_mu);
    last = to_json(r, false);
    last["at"] = storage::utc_from_ns(
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count());
  }

  void loop() {
    auto next = std::chrono::steady_clock::now() + opt.first_delay;
    for (;;) {
      {
        std::unique_lock l(wake_mu);
        if (wake.wait_until(l, next, [this] { return stopping.load(); })) return;
      }
      sweep();
      next = std::chrono::steady_clock::now() + opt.interval;
    }
  }
};

RetentionService::RetentionService(RetentionOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {}

RetentionService::~RetentionService() { stop(); }

void RetentionService::start() {
  if (impl_->opt.interval.count() <= 0 || impl_->thread.joinable()) return;
  impl_->thread = std::thread([this] { impl_->loop(); });
}

void RetentionService::stop() {
  {
    std::lock_guard l(impl_->wake_mu);
    impl_->stopping = true;
  }
  impl_->wake.notify_all();
  if (impl_->thread.joinable()) impl_->thread.join();
}

const storage::RetentionPolicy& RetentionService::defaults() const { return impl_->opt.defaults; }

json RetentionService::put_policy(const std::string& pump_id, const json& body, const std::string& by) {
  // Checked here to name the request's field ("retention: samples_days: ...").
  storage::retention_policy_from_json(body, impl_->opt.defaults, "retention");
  std::lock_guard l(impl_->put_mu);
  if (!impl_->writer) impl_->writer.emplace(storage::Historian::open(impl_->opt.db_path, storage::Historian::Mode::write));
  auto& h = *impl_->writer;
  if (!h.find_pump(pump_id)) throw NotFoundError("no pump '" + pump_id + "'");
  h.put_retention_policy(pump_id, body.dump(), by);
  return *retention_view(h, pump_id, impl_->opt.defaults);
}

storage::SweepReport RetentionService::sweep_now() { return impl_->sweep(); }

json RetentionService::last_sweep() const {
  std::lock_guard l(impl_->report_mu);
  return impl_->last;
}

}  // namespace ambdiag::server
