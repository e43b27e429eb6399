// The server's retention (docs/storage.md "Retention", docs/service.md):
// the server's default policy, each pump's own policy over it (GET / PUT
// /api/v1/pumps/{pump_id}/retention), and the sweep, run on a thread of its
// own at the start and then periodically (storage/retention.h says what it
// drops and what it never drops). Its figures go to /metrics.
//
// Threads: every public call may come from any thread; the sweep has its
// own write connection, a PUT opens another.
#pragma once

#include <chrono>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "ambdiag/storage/historian.h"
#include "ambdiag/storage/retention.h"

namespace ambdiag::server {

class MetricsRegistry;

struct RetentionOptions {
  std::string db_path;
  // The server's default policy: the built-in one, or `ambdiag serve
  // --retention FILE` over it (retention_defaults_from_file).
  storage::RetentionPolicy defaults;
  // Between sweeps (`--retention-interval S`); zero: no periodic sweep
  // (the policies are kept and shown; `ambdiag db retention` sweeps).
  std::chrono::milliseconds interval{600'000};
  // The first sweep this long after start() (the analysis queues what it
  // must redo first, and such runs are kept).
  std::chrono::milliseconds first_delay{2'000};
  MetricsRegistry* metrics = nullptr;  // dropped bytes and runs, sweeps, the last sweep's time
  bool verbose = true;                 // a line per sweep that dropped something, on stderr
};

// The built-in defaults with the JSON file's keys over them. InputError
// naming the file and the key ("--retention F: samples_days: ...").
storage::RetentionPolicy retention_defaults_from_file(const std::string& path);

// GET /api/v1/pumps/{pump_id}/retention: {"pump_id", "policy" (effective),
// "source": "pump"|"defaults", "override" (the pump's own keys, {} when
// none), "defaults", "version"?, "created_at"?, "created_by"?, "usage"};
// nullopt for an unknown pump.
std::optional<nlohmann::json> retention_view(storage::Historian& h, const std::string& pump_id,
                                             const storage::RetentionPolicy& defaults);

class RetentionService {
 public:
  explicit RetentionService(RetentionOptions options);
  ~RetentionService();  // stops and joins
  RetentionService(const RetentionService&) = delete;
  RetentionService& operator=(const RetentionService&) = delete;

  void start();  // the sweep thread (nothing when the interval is zero)
  void stop();   // ends the sweep between two transactions; joins. Idempotent.

  const storage::RetentionPolicy& defaults() const;
  // PUT: `body` (an object of the policy's keys) becomes the pump's next
  // policy version, by `by`. InputError naming the key; NotFoundError for
  // an unknown pump. Returns the view.
  nlohmann::json put_policy(const std::string& pump_id, const nlohmann::json& body, const std::string& by);
  // One sweep now, on the calling thread (tests; the thread's sweeps are the same).
  storage::SweepReport sweep_now();
  // The last sweep's report (to_json without the runs), null before the first.
  nlohmann::json last_sweep() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace ambdiag::server
