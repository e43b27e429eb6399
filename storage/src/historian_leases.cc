// Historian: ingest groups' leases (table ingest_leases, schema v7;
// ingest_lease.h). Every change is a compare-and-set UPDATE whose WHERE
// names what the caller saw or holds (epoch, holder, renewals): SQLite
// serialises the writers, and on PostgreSQL the row lock does, so two
// standbys never both take a group and a taken-over holder never renews.
#include <chrono>

#include "ambdiag/storage/historian.h"
#include "historian_impl.h"

namespace ambdiag::storage {

namespace {

#define AMBDIAG_LEASE_COLUMNS \
  "ingest_group, partitions, holder, epoch, renewals, lease_ms, acquired_at, renewed_at, expires_at"

IngestLease read_lease_row(const Stmt& s) {
  IngestLease l;
  l.group = s.col_text(0);
  l.partitions = s.col_text(1);
  l.holder = s.col_text(2);
  l.epoch = s.col_int(3);
  l.renewals = s.col_int(4);
  l.lease_ms = s.col_int(5);
  l.acquired_at = s.col_opt_text(6).value_or("");
  l.renewed_at = s.col_opt_text(7).value_or("");
  l.expires_at = s.col_opt_text(8).value_or("");
  return l;
}

// Now and now + lease on this host's clock (informational columns).
struct LeaseTimes {
  std::string now, expires;
};
LeaseTimes lease_times(std::int64_t lease_ms) {
  const auto now_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                          std::chrono::system_clock::now().time_since_epoch())
                          .count();
  return {utc_from_ns(now_ms * 1'000'000), utc_from_ns((now_ms + lease_ms) * 1'000'000)};
}

void check_lease_ms(std::int64_t lease_ms, const std::string& ctx) {
  if (lease_ms < 1) throw InputError(ctx + ": lease_ms must be >= 1");
}

// The compare-and-set: runs the bound UPDATE and commits `tx` only if it
// matched the one row (else `tx` rolls back, having changed nothing).
bool set_if_matched(Historian::Impl& impl, Stmt& update, Transaction& tx) {
  update.run();
  if (impl.db.changes() != 1) return false;
  tx.commit();
  return true;
}

}  // namespace

IngestLease Historian::join_ingest_group(const std::string& group, const std::string& partitions,
                                         std::int64_t lease_ms) {
  impl_->require_writer("join_ingest_group");
  const std::string ctx = "ingest group " + quoted(group);
  if (group.empty()) throw InputError("ingest group: the name must not be empty");
  if (partitions.empty()) throw InputError(ctx + ": the partition list must not be empty");
  check_lease_ms(lease_ms, ctx);
  Transaction tx(impl_->db, Transaction::Kind::write);
  impl_->stmt(
          "INSERT INTO ingest_leases (ingest_group, partitions, lease_ms, created_at) VALUES (?, ?, ?, ?) "
          "ON CONFLICT (ingest_group) DO NOTHING")
      .bind(1, group)
      .bind(2, partitions)
      .bind(3, lease_ms)
      .bind(4, now_utc())
      .run();
  auto held = find_ingest_lease(group);
  if (!held) throw StorageError(ctx + ": neither inserted nor held");
  if (held->partitions != partitions) {
    if (!held->holder.empty())
      throw InputError(ctx + " covers DDS partitions '" + held->partitions + "' and is held by " +
                       quoted(held->holder) + " (epoch " + std::to_string(held->epoch) + ", renewed at " +
                       held->renewed_at + "); this server reads '" + partitions +
                       "': servers of one group must read the same partitions (stop the group's servers first, "
                       "a clean stop releases it, or name another group)");
    impl_->stmt("UPDATE ingest_leases SET partitions = ? WHERE ingest_group = ? AND holder = ''")
        .bind(1, partitions)
        .bind(2, group)
        .run();
    held->partitions = partitions;
  }
  tx.commit();
  return *held;
}

std::optional<IngestLease> Historian::find_ingest_lease(const std::string& group) {
  auto& s = impl_->stmt("SELECT " AMBDIAG_LEASE_COLUMNS " FROM ingest_leases WHERE ingest_group = ?");
  s.bind(1, group);
  if (!s.step()) return std::nullopt;
  auto l = read_lease_row(s);
  s.reset();
  return l;
}

std::vector<IngestLease> Historian::list_ingest_leases() {
  auto& s = impl_->stmt("SELECT " AMBDIAG_LEASE_COLUMNS " FROM ingest_leases ORDER BY ingest_group");
  std::vector<IngestLease> out;
  while (s.step()) out.push_back(read_lease_row(s));
  return out;
}

std::optional<IngestLease> Historian::take_ingest_lease(const IngestLease& seen, const std::string& holder,
                                                        const std::string& partitions, std::int64_t lease_ms) {
  impl_->require_writer("take_ingest_lease");
  if (holder.empty()) throw InputError("ingest group " + quoted(seen.group) + ": the holder's name must not be empty");
  check_lease_ms(lease_ms, "ingest group " + quoted(seen.group));
  const auto t = lease_times(lease_ms);
  Transaction tx(impl_->db, Transaction::Kind::write);
  impl_->stmt(
          "UPDATE ingest_leases SET holder = ?, epoch = epoch + 1, renewals = renewals + 1, lease_ms = ?, "
          "acquired_at = ?, renewed_at = ?, expires_at = ? "
          "WHERE ingest_group = ? AND holder = ? AND epoch = ? AND renewals = ? AND partitions = ?")
      .bind(1, holder)
      .bind(2, lease_ms)
      .bind(3, t.now)
      .bind(4, t.now)
      .bind(5, t.expires)
      .bind(6, seen.group)
      .bind(7, seen.holder)
      .bind(8, seen.epoch)
      .bind(9, seen.renewals)
      .bind(10, partitions)
      .run();
  if (impl_->db.changes() != 1) return std::nullopt;
  auto taken = find_ingest_lease(seen.group);
  tx.commit();
  return taken;
}

bool Historian::renew_ingest_lease(const std::string& group, const std::string& holder, std::int64_t epoch,
                                   std::int64_t lease_ms) {
  impl_->require_writer("renew_ingest_lease");
  check_lease_ms(lease_ms, "ingest group " + quoted(group));
  const auto t = lease_times(lease_ms);
  Transaction tx(impl_->db, Transaction::Kind::write);
  auto& renew = impl_->stmt(
      "UPDATE ingest_leases SET renewals = renewals + 1, lease_ms = ?, renewed_at = ?, expires_at = ? "
      "WHERE ingest_group = ? AND holder = ? AND epoch = ?");
  renew.bind(1, lease_ms).bind(2, t.now).bind(3, t.expires).bind(4, group).bind(5, holder).bind(6, epoch);
  return set_if_matched(*impl_, renew, tx);
}

bool Historian::release_ingest_lease(const std::string& group, const std::string& holder, std::int64_t epoch) {
  impl_->require_writer("release_ingest_lease");
  Transaction tx(impl_->db, Transaction::Kind::write);
  auto& release = impl_->stmt(
      "UPDATE ingest_leases SET holder = '', renewals = renewals + 1, expires_at = ? "
      "WHERE ingest_group = ? AND holder = ? AND epoch = ?");
  const std::string now = now_utc();  // bound text is not copied: it must outlive the run
  release.bind(1, now).bind(2, group).bind(3, holder).bind(4, epoch);
  return set_if_matched(*impl_, release, tx);
}

}  // namespace ambdiag::storage
