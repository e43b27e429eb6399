// Retention: how long the historian keeps each pump's bulk data, and the
// sweep that drops what a pump's policy no longer keeps (schema v8;
// docs/storage.md "Retention"). The Historian's calls are declared in
// historian.h under "retention" and implemented in historian_retention.cc.
//
// What a policy may drop, and only that:
//   - a run's raw samples (the chunks: 6 MB a run, the bulk of the file),
//     by age (`samples_days`, counted from when the historian received the
//     run: runs.created_at, the server clock) and/or by size
//     (`samples_bytes`: the pump's samples held, oldest runs dropped first);
//   - the files of a run's analysis jobs (frf.csv, the figures, fit_model.json),
//     `frf_days` after the run was received and never before its
//     samples are gone (FRFs are kept at least as long as samples);
//   - monitoring snapshots older than `monitoring_days` (by their time_ns).
// Kept always: run headers, analysis results, trend points, alarms and their
// journal, models, references, jobs, the reference and explain jobs' files.
// Never dropped: a run still receiving, a run of any reference version of its
// pump, a run an alarm that is not `normal` names, a run a queued or running
// job names.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>  // the full header brings std::quoted into every includer of historian.h

namespace ambdiag::storage {

// nullopt: kept for ever. The built-in defaults are the member initialisers.
struct RetentionPolicy {
  std::optional<double> samples_days = 90.0;
  std::optional<std::int64_t> samples_bytes;  // per pump
  std::optional<double> frf_days = 730.0;
  std::optional<double> monitoring_days;
};

// The policy's JSON keys, in their order.
inline constexpr const char* kRetentionKeys[] = {"samples_days", "samples_bytes", "frf_days", "monitoring_days"};

// `j` (an object) over `base`: each key given replaces base's value (null:
// kept for ever), keys not given keep base's. Days: a number in 0..36500;
// samples_bytes: an integer in 0..2^62. InputError "SOURCE: KEY: ..." for an
// unknown key, a wrong type or a value out of range; "SOURCE: ..." for a
// body that is not an object.
RetentionPolicy retention_policy_from_json(const nlohmann::json& j, const RetentionPolicy& base,
                                           const std::string& source);
// Every key, null where kept for ever.
nlohmann::json to_json(const RetentionPolicy& p);

// One version of a pump's own policy: the keys it sets over the server's
// defaults (the PUT body, validated), who set it and when.
struct RetentionVersion {
  std::string pump_id;
  int version = 0;
  std::string policy_json;  // a JSON object of kRetentionKeys (a subset)
  std::string created_at, created_by;
};

// What a pump holds now, and what retention dropped of it.
struct RetentionUsage {
  std::int64_t runs_with_samples = 0, samples_bytes_held = 0;  // samples_bytes counts these
  std::int64_t runs_samples_dropped = 0, samples_bytes_dropped = 0;
  std::int64_t runs_frf_dropped = 0, frf_bytes_dropped = 0;
};

struct SweepOptions {
  // The policies' clock (runs older than now - days are dropped). The lease
  // runs on the real clock whatever this says.
  std::chrono::system_clock::time_point now = std::chrono::system_clock::now();
  // Report what would be dropped, change nothing (no lease taken).
  bool dry_run = false;
  // At most about this many bytes of chunks deleted per transaction (at
  // least one chunk), so a sweep never holds the write lock for long; a run
  // larger than that is marked `dropping` in its first transaction and
  // finished in the next ones.
  std::int64_t max_bytes_per_transaction = 16 << 20;
  std::int64_t max_monitoring_rows_per_transaction = 20000;
  // After each transaction, wait as long as it took (at least 2 ms) before
  // the next, so that a writer waiting for the lock (ingest) gets it: the
  // sweep holds the write lock at most about half the time.
  bool yield_between_transactions = true;
  // The lease: one sweep at a time per database. `holder` names this sweep
  // ("" : pid@host); the lease lasts lease_ttl past its last renewal (a
  // sweep that died frees it then).
  std::string holder;
  std::chrono::seconds lease_ttl{120};
  // Asked between transactions: true stops the sweep (report.stopped).
  std::function<bool()> stop;
  // Called after each committed transaction that dropped something (tests
  // use it to crash at a known point).
  std::function<void()> after_commit;
};

struct SweptRun {
  std::string run_id, pump_id;
  std::string what;    // "samples" or "frf"
  std::int64_t bytes = 0;  // dropped (dry run: that would be)
  std::string reason;  // "age", "size", "interrupted" (a drop a crashed sweep began)
};

struct SweepReport {
  bool dry_run = false;
  std::string skipped;  // non-empty: the sweep did not run (another sweep holds the lease: who, until when)
  bool stopped = false; // options.stop asked it to stop, or the lease was lost
  std::vector<SweptRun> runs;  // in the order dropped
  std::int64_t samples_runs = 0, samples_bytes = 0;
  std::int64_t frf_runs = 0, frf_bytes = 0;
  std::int64_t monitoring_rows = 0;
  std::int64_t pumps = 0;         // pumps looked at
  std::int64_t partitions = 0;    // PostgreSQL: day partitions of sample_chunks dropped whole
  // PostgreSQL: the kept runs whose chunks were moved out of a day
  // partition (to sample_chunks_kept) so that it could go whole; their bytes.
  std::int64_t moved_runs = 0, moved_bytes = 0;
  std::int64_t transactions = 0;  // write transactions that dropped something
  double transactions_s = 0;      // their time, from BEGIN IMMEDIATE granted to COMMIT
  double longest_transaction_s = 0;  // the longest a writer (ingest) could have waited for the sweep
  double seconds = 0;             // the whole sweep
  std::vector<std::string> errors;  // pumps whose stored policy did not read (the defaults were used)
};
// {"dry_run", "skipped"?, "stopped", "pumps", "samples": {"runs", "bytes"},
//  "frf": {"runs", "bytes"}, "monitoring_rows", "partitions",
//  "moved": {"runs", "bytes"}, "transactions",
//  "transactions_s", "longest_transaction_s", "seconds", "errors",
//  "runs"?: [{"run_id", "pump_id", "what", "bytes", "reason"}]}
nlohmann::json to_json(const SweepReport& r, bool with_runs);

}  // namespace ambdiag::storage
