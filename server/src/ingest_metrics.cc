// Ingest's counters (ingest.h) read at each scrape of GET /metrics.
#include <atomic>

#include "ambdiag/server/ingest.h"
#include "ambdiag/server/ingest_group.h"
#include "ambdiag/server/metrics.h"

namespace ambdiag::server {

void register_ingest_metrics(MetricsRegistry& registry, const Ingest& ingest) {
  const IngestCounters& c = ingest.counters();
  registry.collected("ambdiag_ingest_runs_total",
                     "Runs whose end this server stored, by outcome (complete: count and checksum verified).",
                     MetricType::counter, {"outcome"}, [&c] {
                       return std::vector<MetricSample>{
                           {{"complete"}, static_cast<double>(c.runs_complete.load())},
                           {{"incomplete"}, static_cast<double>(c.runs_incomplete.load())}};
                     });
  const struct {
    const char* name;
    const char* help;
    const std::atomic<int64_t>& value;
  } counters[] = {
      {"ambdiag_ingest_run_headers_total",
       "Run headers stored (a header an agent sends again counts again; run.new events count runs).",
       c.headers},
      {"ambdiag_ingest_blocks_stored_total", "Sample blocks stored.", c.blocks_stored},
      {"ambdiag_ingest_blocks_duplicate_total", "Sample blocks received again and ignored (already held).",
       c.blocks_duplicate},
      {"ambdiag_ingest_stored_bytes_total", "Sample bytes stored.", c.bytes_stored},
      {"ambdiag_ingest_monitoring_snapshots_total", "Monitoring snapshots stored.", c.monitoring_stored},
      {"ambdiag_ingest_commits_total", "Historian transactions of ingest.", c.commits},
      {"ambdiag_ingest_storage_errors_total",
       "Ingest commits that failed (nothing acknowledged; the agents re-send).", c.storage_errors},
      {"ambdiag_ingest_blocks_refused_by_dds_total",
       "Blocks refused by the full DDS reader (re-sent by DDS: back-pressure, not loss).",
       c.blocks_rejected_by_dds},
      {"ambdiag_ingest_commits_fenced_total",
       "Ingest commits rolled back because another server had taken over the ingest group (nothing acknowledged).",
       c.commits_fenced},
  };
  for (const auto& k : counters)
    registry.collected_value(k.name, k.help, MetricType::counter,
                             [&v = k.value] { return static_cast<double>(v.load()); });
  registry.collected_value("ambdiag_ingest_queue_bytes", "Bytes received and validated, not yet committed.",
                           MetricType::gauge, [&c] { return static_cast<double>(c.queue_bytes.load()); });
  // Every reason from the start (at 0), so that rate() sees the first one.
  registry.collected("ambdiag_ingest_rejected_samples_total",
                     "DDS samples rejected (logged, not stored) by reason.", MetricType::counter, {"reason"},
                     [&c] {
                       auto by = c.rejected_by_reason();
                       for (const char* r : {"version", "oversized", "size", "checksum", "non_finite",
                                             "header", "conflict", "run_end", "monitoring", "pump_partition", "dds_security"})
                         by.try_emplace(r, 0);
                       std::vector<MetricSample> out;
                       for (const auto& [reason, n] : by) out.push_back({{reason}, static_cast<double>(n)});
                       return out;
                     });
}

void register_ingest_group_metrics(MetricsRegistry& registry, const IngestGroup& group) {
  const auto one = [&group](auto value) {
    return [&group, value] {
      const auto s = group.status();
      return std::vector<MetricSample>{{{s.group}, value(s)}};
    };
  };
  using S = IngestGroup::Status;
  registry.collected("ambdiag_ingest_group_holder",
                     "1 while this server holds the ingest group (ingests its pumps), 0 while it stands by.",
                     MetricType::gauge, {"group"}, one([](const S& s) { return s.holding ? 1.0 : 0.0; }));
  registry.collected("ambdiag_ingest_group_takeovers_total", "Times this server took the ingest group.",
                     MetricType::counter, {"group"}, one([](const S& s) { return static_cast<double>(s.takeovers); }));
  registry.collected("ambdiag_ingest_group_lost_total",
                     "Times another server took the ingest group over while this one held it (it had not renewed).",
                     MetricType::counter, {"group"}, one([](const S& s) { return static_cast<double>(s.lost); }));
}

}  // namespace ambdiag::server
