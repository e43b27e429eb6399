// Ingest groups (table ingest_leases, schema v7; docs/streaming.md "Several
// servers: ingest groups and failover"): the pumps whose DDS partitions a
// group covers are ingested by exactly one `ambdiag serve` at a time, the
// group's holder; others naming the group stand by and take it over when
// the holder stops renewing its lease.
//
// The database decides. A holder is (holder, epoch): each new holder adds 1
// to the epoch, and a holder's every write to the lease row (a renewal, and
// the check in each ingest commit's own transaction) names its epoch, so a
// holder that was taken over (paused past its lease, then woken) finds no
// row to update and stops: it can no longer commit or acknowledge. Expiry
// is observed, not computed from clocks: a standby takes the group once the
// row's (holder, epoch, renewals) has not changed for lease_ms by its own
// monotonic clock (so no two hosts' clocks are ever compared), or at once
// when the holder released it.
#pragma once

#include <cstdint>
#include <string>

namespace ambdiag::storage {

struct IngestLease {
  std::string group;
  std::string partitions;  // the DDS partitions the group reads, as registered (comma-separated, sorted)
  std::string holder;      // the instance holding it; empty: nobody (never held, or released)
  std::int64_t epoch = 0;  // the fencing token: +1 at each new holder
  std::int64_t renewals = 0;  // +1 at each renewal and each ingest commit of the holder
  std::int64_t lease_ms = 0;  // the holder's lease: how long standbys wait for a renewal
  // Holder's clock, ISO 8601 UTC, for people (health, the table): empty
  // before the first holder.
  std::string acquired_at, renewed_at, expires_at;

  bool same_state(const IngestLease& o) const {
    return holder == o.holder && epoch == o.epoch && renewals == o.renewals;
  }
};

}  // namespace ambdiag::storage
