#include "ambdiag/server/ingest_group.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <thread>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/monitoring.h"

namespace ambdiag::server {

namespace {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

std::string default_instance() {
  char host[256] = {};
  if (gethostname(host, sizeof host - 1) != 0 || host[0] == '\0') std::snprintf(host, sizeof host, "localhost");
  return std::string(host) + ":" + std::to_string(getpid());
}

std::string utc_now() {  // to the millisecond, as the lease row's times
  const auto ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  return storage::utc_from_ns(ms * 1'000'000);
}

// Sleeps `d` in slices, returning early once `flag` is set.
void sleep_unless(const std::atomic<bool>& flag, std::chrono::milliseconds d) {
  const auto until = Clock::now() + d;
  while (!flag.load() && Clock::now() < until) std::this_thread::sleep_for(std::min<Clock::duration>(20ms, until - Clock::now()));
}

}  // namespace

std::string partitions_key(const std::vector<std::string>& partitions) {
  if (partitions.empty()) throw InputError("ingest partitions: the list must not be empty");
  std::vector<std::string> p = partitions;
  for (const auto& name : p)
    if (name.empty() || name.find(',') != std::string::npos)
      throw InputError("ingest partitions: '" + name + "' is not a DDS partition name (empty, or contains ',')");
  std::sort(p.begin(), p.end());
  p.erase(std::unique(p.begin(), p.end()), p.end());
  std::string key;
  for (const auto& name : p) key += (key.empty() ? "" : ",") + name;
  return key;
}

// The lease row as last seen, and since when (this process' clock) it has
// not changed: the holder is gone once that lasts its lease.
struct IngestGroup::Seen {
  storage::IngestLease row;
  Clock::time_point since;
};

IngestGroup::IngestGroup(storage::Historian& historian, IngestOptions ingest, IngestGroupOptions opt)
    : opt_(std::move(opt)),
      partitions_(partitions_key(ingest.partitions)),
      lease_db_(storage::Historian::open(historian.path(), storage::Historian::Mode::write)),
      ingest_(historian, [&] {
        // In each commit's transaction: still ours, with our epoch? (renews it too)
        ingest.fence = [this](storage::Historian& h) {
          return h.renew_ingest_lease(opt_.group, opt_.instance, epoch_.load(), opt_.lease.count());
        };
        return std::move(ingest);
      }()) {
  if (opt_.instance.empty()) opt_.instance = default_instance();
  if (opt_.lease < 100ms || opt_.lease > 600s)
    throw InputError("ingest lease: must be 0.1 to 600 s, not " + std::to_string(opt_.lease.count()) + " ms");
  if (opt_.renew_every.count() <= 0) opt_.renew_every = opt_.lease / 3;
  if (opt_.poll_every.count() <= 0) opt_.poll_every = std::min<std::chrono::milliseconds>(250ms, opt_.lease / 12);
  if (opt_.renew_every >= opt_.lease)
    throw InputError("ingest lease: renewing every " + std::to_string(opt_.renew_every.count()) +
                     " ms would let a " + std::to_string(opt_.lease.count()) + " ms lease lapse");
  const auto row = lease_db_.join_ingest_group(opt_.group, partitions_, opt_.lease.count());
  status_ = {opt_.group, partitions_, opt_.instance, false, row.epoch, row.holder, 0, 0, "",
             static_cast<double>(opt_.lease.count()) / 1000.0};
}

IngestGroup::~IngestGroup() = default;

void IngestGroup::log(const std::string& msg) const {
  if (!opt_.verbose) return;
  const std::string line = "ambdiag serve: ingest group '" + opt_.group + "': " + msg + "\n";
  std::fputs(line.c_str(), stderr);
}

IngestGroup::Status IngestGroup::status() const {
  std::lock_guard lock(mu_);
  return status_;
}

nlohmann::json IngestGroup::health() const {
  const Status s = status();
  nlohmann::json j = {{"group", s.group},         {"partitions", s.partitions}, {"instance", s.instance},
                      {"role", s.holding ? "holder" : "standby"}, {"epoch", s.epoch},
                      {"holder", s.holder},       {"takeovers", s.takeovers}, {"lost", s.lost},
                      {"lease_s", s.lease_s}};
  if (s.holding) j["holding_since"] = s.holding_since;
  return j;
}

void IngestGroup::run(const std::atomic<bool>& stop_flag) {
  std::optional<Seen> seen;
  while (!stop_flag.load()) {
    try {
      if (const auto lease = standby_step(seen)) {
        hold(*lease, stop_flag);
        seen.reset();  // watch the next holder from now
        continue;
      }
    } catch (const std::exception& e) {  // a locked or failing database: try again
      log(std::string("lease: ") + e.what());
    }
    sleep_unless(stop_flag, opt_.poll_every);
  }
}

std::optional<storage::IngestLease> IngestGroup::standby_step(std::optional<Seen>& seen) {
  auto row = lease_db_.find_ingest_lease(opt_.group);
  if (!row) row = lease_db_.join_ingest_group(opt_.group, partitions_, opt_.lease.count());  // deleted by hand
  const auto now = Clock::now();
  if (!seen || !seen->row.same_state(*row)) seen = Seen{*row, now};
  {
    std::lock_guard lock(mu_);
    status_.holder = row->holder;
    status_.epoch = row->epoch;
  }
  if (row->partitions != partitions_) {
    if (!warned_partitions_)
      log("standing by only: the group covers partitions '" + row->partitions + "', this server reads '" +
          partitions_ + "'");
    warned_partitions_ = true;
    return std::nullopt;
  }
  const bool lapsed = row->holder.empty() || now - seen->since >= std::chrono::milliseconds(row->lease_ms);
  if (!lapsed) return std::nullopt;
  auto taken = lease_db_.take_ingest_lease(*row, opt_.instance, partitions_, opt_.lease.count());
  if (taken)
    log("taken (epoch " + std::to_string(taken->epoch) + ")" +
        (row->holder.empty() ? std::string()
                             : ", from " + row->holder + ", whose lease lapsed (no renewal for " +
                                   std::to_string(row->lease_ms) + " ms)") +
        "; ingesting partitions " + partitions_);
  return taken;
}

void IngestGroup::hold(const storage::IngestLease& lease, const std::atomic<bool>& stop_flag) {
  epoch_ = lease.epoch;
  {
    std::lock_guard lock(mu_);
    status_.holding = true;
    status_.epoch = lease.epoch;
    status_.holder = opt_.instance;
    status_.holding_since = utc_now();
    ++status_.takeovers;
  }
  std::atomic<bool> lost{false}, ended{false};
  Ingest::End end = Ingest::End::stopped;
  bool failed = false;
  std::thread ingest_thread([&] {
    try {
      end = ingest_.run(stop_flag, lost);
    } catch (const std::exception& e) {  // e.g. DDS refused the participant: let another server try
      log(std::string("ingest failed: ") + e.what());
      failed = true;
    }
    ended = true;
  });
  // Renew until stopped, or until the database says another holds it. A
  // renewal that fails on the database (locked, I/O) is retried: the
  // database alone says whether the lease lapsed, and the next commit's
  // fence finds out if it did.
  auto next_renewal = Clock::now() + opt_.renew_every;
  while (!stop_flag.load() && !ended.load()) {
    std::this_thread::sleep_for(20ms);
    if (Clock::now() < next_renewal) continue;
    next_renewal = Clock::now() + opt_.renew_every;
    try {
      if (!lease_db_.renew_ingest_lease(opt_.group, opt_.instance, lease.epoch, opt_.lease.count())) {
        lost = true;
        break;
      }
    } catch (const std::exception& e) {
      log(std::string("renewing the lease: ") + e.what());
    }
  }
  ingest_thread.join();
  const bool was_lost = lost.load() || end == Ingest::End::fenced;
  if (was_lost) {
    log("lost (epoch " + std::to_string(lease.epoch) +
        "): another server took it over while this one did not renew (paused, or the database was slow); "
        "ingest stopped, nothing more acknowledged; standing by");
  } else {
    try {
      if (lease_db_.release_ingest_lease(opt_.group, opt_.instance, lease.epoch)) log("released");
    } catch (const std::exception& e) {
      log(std::string("releasing the lease: ") + e.what() + " (a standby takes over when it lapses)");
    }
  }
  {
    std::lock_guard lock(mu_);
    status_.holding = false;
    status_.holding_since.clear();
    if (was_lost) ++status_.lost;
  }
  if (failed) sleep_unless(stop_flag, opt_.lease);  // released: a standby of another process goes first
}

}  // namespace ambdiag::server
