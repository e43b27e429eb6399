// Ingest's counters (ingest.h) read at each scrape of GET /metrics.
#include <atomic>

#include "ambdiag/server/ingest.h"
#include "ambdiag/server/metrics.h"

namespace ambdiag::server {

namespace {

std::vector<MetricSample> one(const std::atomic<int64_t>& v) { return {{{}, static_cast<double>(v.load())}}; }

}  // namespace

void register_ingest_metrics(MetricsRegistry& registry, const Ingest& ingest) {
  const IngestCounters& c = ingest.counters();
  registry.collected("ambdiag_ingest_runs_total", "Runs whose end this server stored, by outcome (complete: count and checksum verified).",
                     MetricType::counter, {"outcome"}, [&c] {
                       return std::vector<MetricSample>{{{"complete"}, static_cast<double>(c.runs_complete.load())},
                                                        {{"incomplete"}, static_cast<double>(c.runs_incomplete.load())}};
                     });
  registry.collected("ambdiag_ingest_run_headers_total", "Run headers stored (a header an agent sends again counts again; run.new events count runs).", MetricType::counter, {},
                     [&c] { return one(c.headers); });
  registry.collected("ambdiag_ingest_blocks_stored_total", "Sample blocks stored.", MetricType::counter, {},
                     [&c] { return one(c.blocks_stored); });
  registry.collected("ambdiag_ingest_blocks_duplicate_total", "Sample blocks received again and ignored (already held).",
                     MetricType::counter, {}, [&c] { return one(c.blocks_duplicate); });
  registry.collected("ambdiag_ingest_stored_bytes_total", "Sample bytes stored.", MetricType::counter, {},
                     [&c] { return one(c.bytes_stored); });
  registry.collected("ambdiag_ingest_monitoring_snapshots_total", "Monitoring snapshots stored.", MetricType::counter, {},
                     [&c] { return one(c.monitoring_stored); });
  registry.collected("ambdiag_ingest_commits_total", "Historian transactions of ingest.", MetricType::counter, {},
                     [&c] { return one(c.commits); });
  registry.collected("ambdiag_ingest_storage_errors_total", "Ingest commits that failed (nothing acknowledged; the agents re-send).",
                     MetricType::counter, {}, [&c] { return one(c.storage_errors); });
  registry.collected("ambdiag_ingest_queue_bytes", "Bytes received and validated, not yet committed.", MetricType::gauge, {},
                     [&c] { return one(c.queue_bytes); });
  registry.collected("ambdiag_ingest_blocks_refused_by_dds_total",
                     "Blocks refused by the full DDS reader (re-sent by DDS: back-pressure, not loss).", MetricType::counter, {},
                     [&c] { return one(c.blocks_rejected_by_dds); });
  // Every reason from the start (at 0), so that rate() sees the first one.
  registry.collected("ambdiag_ingest_rejected_samples_total", "DDS samples rejected (logged, not stored) by reason.",
                     MetricType::counter, {"reason"}, [&c] {
                       auto by = c.rejected_by_reason();
                       for (const char* r : {"version", "oversized", "size", "checksum", "non_finite", "header", "conflict",
                                             "run_end", "monitoring"})
                         by.try_emplace(r, 0);
                       std::vector<MetricSample> out;
                       for (const auto& [reason, n] : by) out.push_back({{reason}, static_cast<double>(n)});
                       return out;
                     });
}

}  // namespace ambdiag::server
