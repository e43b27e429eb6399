// Ingest groups: several `ambdiag serve` processes on one database, one of
// them ingesting a group's pumps (its DDS partitions) at a time, the others
// standing by to take over (docs/streaming.md "Several servers: ingest
// groups and failover").
//
// The holder is decided in the database (storage/ingest_lease.h): the
// holder renews its lease every `renew_every` and with every ingest commit;
// a standby looks every `poll_every` and takes the group once the lease row
// has not changed for the holder's lease (by the standby's own clock), or
// at once when the holder released it on a clean stop. Only the holder
// runs Ingest (DDS readers, acks); a standby has no DDS endpoint at all.
// Fencing: every ingest commit checks, in its own transaction, that this
// process still holds the group with its epoch; a holder paused past its
// lease and woken finds it taken over, its batch rolls back unacknowledged
// and it becomes a standby.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

#include <nlohmann/json.hpp>

#include "ambdiag/server/ingest.h"
#include "ambdiag/storage/historian.h"

namespace ambdiag::server {

class MetricsRegistry;

struct IngestGroupOptions {
  std::string group = "default";
  // This process in the lease row and the logs, for people; empty: HOST:PID.
  // The epoch, not the name, tells holders apart: names may repeat.
  std::string instance;
  std::chrono::milliseconds lease{3000};
  std::chrono::milliseconds renew_every{0};  // 0: lease / 3
  std::chrono::milliseconds poll_every{0};   // 0: lease / 12, at most 250 ms
  bool verbose = true;
};

// The group's DDS partitions as the lease row keeps them: sorted, without
// repeats, joined by ','. Throws InputError for an empty list, an empty
// name or one containing ','.
std::string partitions_key(const std::vector<std::string>& partitions);

class IngestGroup {
 public:
  // Opens a connection of its own on `historian`'s file for the lease and
  // joins the group with `ingest.partitions` (InputError when the group is
  // held with other partitions, or for bad options: nothing runs then).
  // `historian` is the ingest's (ingest.h).
  IngestGroup(storage::Historian& historian, IngestOptions ingest, IngestGroupOptions opt);
  ~IngestGroup();
  IngestGroup(const IngestGroup&) = delete;
  IngestGroup& operator=(const IngestGroup&) = delete;

  // Until `stop_flag`: stands by, takes the group when it is free or its
  // lease lapsed, ingests while holding it, stands by again if it is lost;
  // on stop, finishes ingest (last commit, held acks) and releases it.
  // Database errors are logged and retried, never thrown.
  void run(const std::atomic<bool>& stop_flag);

  struct Status {
    std::string group, partitions, instance;
    bool holding = false;
    std::int64_t epoch = 0;  // this process' while holding; else the holder's as last seen
    std::string holder;      // as last seen; empty: nobody
    std::int64_t takeovers = 0;  // times this process took the group
    std::int64_t lost = 0;       // times it lost the group while holding (taken over)
    std::string holding_since;   // ISO 8601 UTC, while holding
    double lease_s = 0;
  };
  Status status() const;
  nlohmann::json health() const;  // one entry of /api/v1/health's "ingest_groups"
  const Ingest& ingest() const { return ingest_; }

 private:
  struct Seen;
  std::optional<storage::IngestLease> standby_step(std::optional<Seen>& seen);
  void hold(const storage::IngestLease& lease, const std::atomic<bool>& stop_flag);
  void log(const std::string& msg) const;

  IngestGroupOptions opt_;
  std::string partitions_;
  storage::Historian lease_db_;  // this thread's own connection
  std::atomic<std::int64_t> epoch_{0};  // the fence reads it from the commit thread
  Ingest ingest_;
  mutable std::mutex mu_;
  Status status_;
  bool warned_partitions_ = false;
};

// The group's state as metrics (GET /metrics): ambdiag_ingest_group_holder,
// _takeovers_total, _lost_total, labelled by group. `group` must outlive
// the registry's scrapes.
void register_ingest_group_metrics(MetricsRegistry& registry, const IngestGroup& group);

}  // namespace ambdiag::server
