#include "ambdiag/server/ingest.h"

#include <pthread.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <optional>
#include <span>
#include <thread>
#include <unordered_map>
#include <utility>

#include "ambdiag/core/checksum.h"
#include "ambdiag/core/error.h"
#include "ambdiag/proto/stream.h"
#include "ambdiag/storage/historian.h"
#include "ingest_commit.h"
#include "ingest_identity.h"
#include "ingest_work.h"

namespace ambdiag::server {

void IngestCounters::reject(const std::string& reason) {
  std::lock_guard lock(mu_);
  ++rejected_[reason];
}

int64_t IngestCounters::rejected_total() const {
  std::lock_guard lock(mu_);
  int64_t n = 0;
  for (const auto& [k, v] : rejected_) n += v;
  return n;
}

std::map<std::string, int64_t> IngestCounters::rejected_by_reason() const {
  std::lock_guard lock(mu_);
  return rejected_;
}

nlohmann::json IngestCounters::to_json() const {
  const int64_t first = first_block_ns.load(), last = last_commit_ns.load();
  nlohmann::json j = {{"headers", headers.load()},
                      {"monitoring_stored", monitoring_stored.load()},
                      {"monitoring_duplicate", monitoring_duplicate.load()},
                      {"storage_errors", storage_errors.load()},
                      {"queue_bytes", queue_bytes.load()},
                      {"queue_peak_bytes", queue_peak_bytes.load()},
                      {"runs_verified_from_digest", runs_verified_from_digest.load()},
                      {"streaming_span_s", first > 0 && last > first ? 1e-9 * static_cast<double>(last - first) : 0.0},
                      {"blocks_received", blocks_received.load()},
                      {"blocks_stored", blocks_stored.load()},
                      {"blocks_duplicate", blocks_duplicate.load()},
                      {"bytes_stored", bytes_stored.load()},
                      {"commits", commits.load()},
                      {"runs_complete", runs_complete.load()},
                      {"runs_incomplete", runs_incomplete.load()},
                      {"blocks_orphan", blocks_orphan.load()},
                      {"blocks_rejected_by_dds", blocks_rejected_by_dds.load()},
                      {"acks_sent", acks_sent.load()},
                      {"blocks_acked_durable", blocks_acked_durable.load()},
                      {"commits_fenced", commits_fenced.load()},
                      {"heartbeats", heartbeats.load()}};
  std::lock_guard lock(mu_);
  nlohmann::json r = nlohmann::json::object();
  int64_t total = 0;
  for (const auto& [k, v] : rejected_) {
    r[k] = v;
    total += v;
  }
  j["rejected"] = total;
  j["rejected_by_reason"] = r;
  return j;
}

namespace {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
}

struct ActiveRun {
  std::string pump_id;
  uint32_t n_channels = 0;
  Clock::time_point last_seen;
  // The run's checksum (of chain_kind, set by block 0) over blocks
  // 0..chain_seq-1 as received (see detail::ValidBlock::chained).
  int64_t chain_seq = 0;
  uint64_t chain_hash = kFnv1a64Init;
  ChecksumKind chain_kind = ChecksumKind::fnv1a64;
};

// Finite unless some float has an all-ones exponent (NaN, infinity); no
// early exit, so the compiler can vectorise it.
bool all_finite(const uint8_t* p, size_t n_bytes) {
  uint32_t bad = 0;
  for (size_t i = 0; i + 4 <= n_bytes; i += 4) {
    uint32_t u;
    std::memcpy(&u, p + i, 4);
    bad |= static_cast<uint32_t>((u & 0x7f800000u) == 0x7f800000u);
  }
  return bad == 0;
}

storage::MonitoringSnapshot from_dds(const ambdiag_stream_MonitoringSnapshot& m) {
  storage::MonitoringSnapshot s;
  s.pump_id = m.pump_id ? m.pump_id : "";
  s.time_ns = m.time_ns;
  s.speed_rpm = m.speed_rpm;
  std::copy(std::begin(m.force_1x_amp_n), std::end(m.force_1x_amp_n), s.force_1x_amp_n.begin());
  std::copy(std::begin(m.force_1x_phase_rad), std::end(m.force_1x_phase_rad), s.force_1x_phase_rad.begin());
  std::copy(std::begin(m.force_2x_amp_n), std::end(m.force_2x_amp_n), s.force_2x_amp_n.begin());
  std::copy(std::begin(m.force_2x_phase_rad), std::end(m.force_2x_phase_rad), s.force_2x_phase_rad.begin());
  std::copy(std::begin(m.orbit_major_m), std::end(m.orbit_major_m), s.orbit_major_m.begin());
  std::copy(std::begin(m.orbit_minor_m), std::end(m.orbit_minor_m), s.orbit_minor_m.begin());
  std::copy(std::begin(m.orbit_center_x_m), std::end(m.orbit_center_x_m), s.orbit_center_x_m.begin());
  std::copy(std::begin(m.orbit_center_y_m), std::end(m.orbit_center_y_m), s.orbit_center_y_m.begin());
  return s;
}

}  // namespace

// The receive thread's side; the commit thread runs detail::Committer.
struct Ingest::Impl {
  Impl(storage::Historian& h, const IngestOptions& o, IngestCounters& c)
      : opt(o),
        counters(c),
        security_log(c),
        db_path(h.path()),
        ep(opt.domain, opt.partitions),
        ws(ep.participant),
        queue(opt.max_queue_bytes),
        committer(h, opt, c, ep.ack) {
    ws.attach_data(ep.header);
    ws.attach_data(ep.block);
    ws.attach_data(ep.end);
    ws.attach_data(ep.status);
    ws.attach_data(ep.monitoring);
  }

  const IngestOptions& opt;
  IngestCounters& counters;
  SecurityLog security_log;  // before the participant: refusals while it starts count too
  WriterPumps writers;
  std::string db_path;
  std::optional<storage::Historian> reader;  // this thread's own read connection
  stream::ServerEndpoints ep;
  dds::WaitSet ws;
  detail::WorkQueue queue;
  detail::Committer committer;
  std::unordered_map<std::string, ActiveRun> active;  // runs receiving, by run_id
  std::unordered_map<std::string, bool> warned_pump_version;

  void reject(const std::string& reason, const std::string& run_id, const std::string& what) {
    counters.reject(reason);
    detail::log_line(opt.verbose, "rejected (" + reason + ") run '" + run_id + "': " + what);
  }

  // True (rejected, counted, logged) if the sample's writer is bound to a
  // pump other than `pump` (docs/streaming.md, "Security").
  bool from_other_pump(const dds::Entity& taken_from, const dds_sample_info_t& info, const std::string& pump,
                       const std::string& run_id, const char* what) {
    const auto bound = writers.bound_pump(taken_from, info.publication_handle);
    if (!bound || *bound == pump) return false;
    reject("pump_partition", run_id, std::string(what) + " names pump '" + pump + "' but its writer publishes in pump '" +
                                         *bound + "''s partition");
    return true;
  }

  void push(detail::Work w) {
    const auto bytes = static_cast<int64_t>(queue.push(std::move(w)));
    counters.queue_bytes = bytes;
    if (bytes > counters.queue_peak_bytes) counters.queue_peak_bytes = bytes;
  }

  void take_status() {
    ep.status.take(4096, [&](const ambdiag_stream_AgentStatus& s, const dds_sample_info_t& info) {
      ++counters.heartbeats;
      if (from_other_pump(ep.status, info, s.pump_id, s.run_id, "heartbeat")) return;
      if (!stream::compatible(s.protocol_version)) {
        if (!warned_pump_version[s.pump_id])
          reject("version", s.run_id, std::string("agent of pump ") + s.pump_id + " speaks protocol " +
                                          stream::version_string(s.protocol_version) + ", server " +
                                          stream::version_string(stream::kProtocolVersion));
        warned_pump_version[s.pump_id] = true;
        return;
      }
      if (auto it = active.find(s.run_id); it != active.end() && it->second.pump_id == s.pump_id)
        it->second.last_seen = Clock::now();
    });
  }

  void take_headers() {
    ep.header.take(256, [&](const ambdiag_stream_RunHeader& h, const dds_sample_info_t& info) {
      const std::string run_id = h.run_id;
      if (!stream::compatible(h.protocol_version)) {
        reject("version", run_id, "protocol " + stream::version_string(h.protocol_version));
        return;
      }
      try {
        storage::RunHeader rh = storage::run_header_from_json(h.header_json, "run header of " + run_id);
        if (rh.run_id != run_id) throw InputError("run header: run_id '" + rh.run_id + "' differs from the key");
        if (rh.channels.size() != h.n_channels)
          throw InputError("run header: n_channels " + std::to_string(h.n_channels) + " but run.json has " +
                           std::to_string(rh.channels.size()) + " channels");
        if (rh.sample_rate_hz != h.sample_rate_hz) throw InputError("run header: sample_rate_hz differs from run.json");
        if (from_other_pump(ep.header, info, rh.pump_id, run_id, "run header")) return;
        const bool known = active.count(run_id) > 0;
        if (!known) {
          active[run_id] = ActiveRun{rh.pump_id, h.n_channels, Clock::now()};
          detail::log_line(opt.verbose, "run " + run_id + " of pump " + rh.pump_id + ": receiving");
        }
        active[run_id].last_seen = Clock::now();
        push(detail::BeginRun{std::move(rh)});  // a repeated header is a no-op in the historian
      } catch (const InputError& e) {
        reject("header", run_id, e.what());
      }
    });
  }

  // A run the historian knows (e.g. after a server restart) becomes active
  // again when its blocks arrive before its header is re-delivered.
  bool lookup_failing = false;  // one message per database outage
  ActiveRun* find_or_load(const std::string& run_id) {
    if (auto it = active.find(run_id); it != active.end()) return &it->second;
    std::optional<storage::RunInfo> info;
    try {
      if (!reader) reader.emplace(storage::Historian::open(db_path, storage::Historian::Mode::read));
      info = reader->find_run(run_id);
      lookup_failing = false;
    } catch (const storage::StorageError& e) {
      // The database restarting: the block is dropped as an orphan for now
      // and the agent re-sends it; the reader reconnects at its next use.
      if (!std::exchange(lookup_failing, true))
        detail::log_line(true, std::string("run ") + run_id + ": cannot look it up (blocks dropped until the "
                                                              "database answers; the agents re-send them): " + e.what());
      return nullptr;
    }
    if (!info || info->status == storage::RunStatus::complete) return nullptr;
    auto& r = active[run_id];
    r = ActiveRun{info->pump_id, static_cast<uint32_t>(info->n_channels), Clock::now()};
    return &r;
  }

  // Validates one block; returns it ready to queue, or nothing (rejected
  // and counted, or orphan).
  std::optional<detail::ValidBlock> validate(const ambdiag_stream_SampleBlock& b) {
    ++counters.blocks_received;
    if (counters.first_block_ns == 0) counters.first_block_ns = steady_ns();
    const std::string run_id = b.run_id;
    const size_t n_bytes = b.payload._length;
    if (!stream::compatible(b.protocol_version)) {
      reject("version", run_id, "block protocol " + stream::version_string(b.protocol_version));
      return std::nullopt;
    }
    if (n_bytes > stream::kMaxBlockPayloadBytes) {
      reject("oversized", run_id, "block " + std::to_string(b.seq) + ": payload " + std::to_string(n_bytes) +
                                      " bytes > limit " + std::to_string(stream::kMaxBlockPayloadBytes));
      return std::nullopt;
    }
    ActiveRun* run = find_or_load(run_id);
    if (!run) {
      ++counters.blocks_orphan;  // header not (yet) seen: the agent re-sends unacknowledged blocks
      return std::nullopt;
    }
    if (b.seq < 0 || b.first_frame < 0 || b.n_frames == 0 ||
        n_bytes != static_cast<size_t>(b.n_frames) * run->n_channels * sizeof(float)) {
      reject("size", run_id, "block " + std::to_string(b.seq) + ": " + std::to_string(n_bytes) + " bytes for " +
                                 std::to_string(b.n_frames) + " frames x " + std::to_string(run->n_channels) +
                                 " channels (seq " + std::to_string(b.seq) + ", first_frame " +
                                 std::to_string(b.first_frame) + ")");
      return std::nullopt;
    }
    // The block's own checksum and, when it extends the run's chain, the
    // run's running one, in one pass. A 1.0 agent sends no checksum_kind:
    // 0, FNV-1a 64.
    const auto kind = checksum_kind_from(b.checksum_kind);
    if (!kind) {
      reject("checksum", run_id, "block " + std::to_string(b.seq) + ": unknown checksum kind " +
                                     std::to_string(b.checksum_kind));
      return std::nullopt;
    }
    const bool extends = b.seq == run->chain_seq && (b.seq == 0 || *kind == run->chain_kind);
    const uint64_t run_before = b.seq == 0 ? run_checksum_init(*kind) : run->chain_hash;
    BlockChecksums sums;
    if (extends)
      sums = block_checksums(*kind, b.payload._buffer, n_bytes, run_before);
    else
      sums.block = block_checksum(*kind, b.payload._buffer, n_bytes);
    if (sums.block != b.checksum) {
      reject("checksum", run_id, "block " + std::to_string(b.seq) + ": checksum mismatch");
      return std::nullopt;
    }
    if (!all_finite(b.payload._buffer, n_bytes)) {
      reject("non_finite", run_id, "block " + std::to_string(b.seq) + ": NaN or infinite sample");
      return std::nullopt;
    }
    run->last_seen = Clock::now();
    detail::ValidBlock v{b.seq,   b.first_frame, b.n_frames, std::vector<uint8_t>(b.payload._buffer, b.payload._buffer + n_bytes),
                         extends, run_before,    sums.run_after, *kind, stream::protocol_minor(b.protocol_version)};
    if (extends) run->chain_seq = b.seq + 1, run->chain_hash = sums.run_after, run->chain_kind = *kind;
    return v;
  }

  // Takes blocks while the queue has room, at most 32 per queued item so the
  // commit thread starts on them early; stops when DDS has no more.
  void take_blocks() {
    constexpr size_t kPerItem = 32;
    for (int round = 0; round < 64 && queue.has_room(); ++round) {
      std::map<std::string, std::vector<detail::ValidBlock>> by_run;
      const size_t n = ep.block.take(kPerItem, [&](const ambdiag_stream_SampleBlock& b, const dds_sample_info_t& info) {
        // A block names no pump: its run does (the header already stored).
        if (const auto it = active.find(b.run_id);
            it != active.end() && from_other_pump(ep.block, info, it->second.pump_id, b.run_id, "block of a run that")) {
          ++counters.blocks_received;
          return;
        }
        if (auto v = validate(b)) by_run[b.run_id].push_back(std::move(*v));
      });
      for (auto& [run_id, blocks] : by_run) push(detail::Blocks{run_id, std::move(blocks)});
      if (n < kPerItem) break;
    }
  }

  void take_ends() {
    ep.end.take(256, [&](const ambdiag_stream_RunEnd& e, const dds_sample_info_t& info) {
      const std::string run_id = e.run_id;
      const auto run = active.find(run_id);
      if (from_other_pump(ep.end, info, run != active.end() ? run->second.pump_id : std::string(e.pump_id ? e.pump_id : ""), run_id,
                          "run end of a run that"))
        return;
      if (!stream::compatible(e.protocol_version)) {
        reject("version", run_id, "run end protocol " + stream::version_string(e.protocol_version));
        return;
      }
      const auto kind = checksum_kind_from(e.checksum_kind);
      if (!kind) {
        reject("run_end", run_id, "unknown checksum kind " + std::to_string(e.checksum_kind));
        return;
      }
      active.erase(run_id);
      push(detail::EndRun{run_id, e.total_frames, e.checksum, *kind, static_cast<bool>(e.aborted), e.reason});
    });
  }

  void take_monitoring() {
    std::vector<storage::MonitoringSnapshot> ok;
    ep.monitoring.take(1024, [&](const ambdiag_stream_MonitoringSnapshot& m, const dds_sample_info_t& info) {
      const std::string pump = m.pump_id ? m.pump_id : "";
      if (from_other_pump(ep.monitoring, info, pump, pump, "monitoring snapshot")) return;
      if (!stream::compatible(m.protocol_version)) {
        reject("version", pump, "monitoring snapshot protocol " + stream::version_string(m.protocol_version));
        return;
      }
      storage::MonitoringSnapshot s = from_dds(m);
      try {
        storage::validate(s);
        ok.push_back(std::move(s));
      } catch (const InputError& e) {
        counters.reject("monitoring");
        detail::log_line(opt.verbose, std::string("rejected (monitoring) pump '") + pump + "': " + e.what());
      }
    });
    if (!ok.empty()) push(detail::Monitoring{std::move(ok)});
  }

  void check_timeouts() {
    const auto now = Clock::now();
    std::vector<std::string> lost;
    for (const auto& [run_id, r] : active) {
      // Seen = a heartbeat naming this run, or one of its blocks.
      if (now - r.last_seen > opt.agent_timeout) lost.push_back(run_id);
    }
    for (const auto& run_id : lost) {
      const std::string reason = "agent of pump " + active[run_id].pump_id + " silent for more than " +
                                 std::to_string(opt.agent_timeout.count() / 1000.0).substr(0, 4) +
                                 " s (no heartbeat, no data) before the run end";
      active.erase(run_id);
      push(detail::MarkIncomplete{run_id, reason});
    }
  }

  void receive_step() {
    // A full queue: blocks wait in DDS (which pushes back on the writers);
    // the waitset would fire at once for them, so wait for room instead.
    if (queue.has_room())
      ws.wait(100ms);
    else
      queue.wait_for_room(20ms);
    take_status();
    take_headers();
    take_blocks();
    counters.blocks_rejected_by_dds = ep.block.rejected_total();
    take_ends();
    take_monitoring();
    check_timeouts();
  }

  void commit_loop(const std::atomic<bool>& receiving_done, const std::atomic<bool>& lost) {
    auto last_commit = Clock::now() - opt.min_commit_interval;
    while (!committer.fenced() && !lost) {  // lost: what is queued is another holder's now
      // Read the flag before popping: once it is set nothing more is pushed,
      // so an empty pop after it means everything is committed.
      const bool done = receiving_done.load();
      // Group commit: under a light load (paced pumps) wait for more work
      // rather than commit every block alone; a busy queue goes at once.
      const auto next = last_commit + opt.min_commit_interval;
      if (!done && Clock::now() < next && queue.bytes() < opt.max_batch_bytes / 2) std::this_thread::sleep_until(next);
      auto batch = queue.pop_batch(opt.max_batch_blocks, opt.max_batch_bytes, 100ms);
      counters.queue_bytes = static_cast<int64_t>(queue.bytes());
      if (batch.empty()) {
        if (done) return;
        continue;
      }
      last_commit = Clock::now();
      committer.commit(batch);
    }
  }
};

Ingest::Ingest(storage::Historian& historian, IngestOptions opt) : historian_(historian), opt_(std::move(opt)) {}

Ingest::~Ingest() = default;

Ingest::End Ingest::run(const std::atomic<bool>& stop_flag) {
  static const std::atomic<bool> never{false};
  return run(stop_flag, never);
}

Ingest::End Ingest::run(const std::atomic<bool>& stop_flag, const std::atomic<bool>& lost_flag) {
  const auto impl = std::make_unique<Impl>(historian_, opt_, counters_);
  std::atomic<bool> receiving_done{false};
  std::thread committer([&] {
    pthread_setname_np(pthread_self(), "ambdiag-commit");  // told apart in top -H, perf, /proc
    impl->commit_loop(receiving_done, lost_flag);
  });
  {
    struct Join {  // the commit thread finishes the queue even if receiving throws
      std::atomic<bool>& done;
      std::thread& t;
      ~Join() {
        done = true;
        t.join();
      }
    } join{receiving_done, committer};
    while (!stop_flag.load() && !lost_flag.load() && !impl->committer.fenced()) impl->receive_step();
  }
  // Lost: the held acks go with the Impl, unsent (the new holder
  // acknowledges what the agents re-send).
  if (impl->committer.fenced() || lost_flag.load()) return End::fenced;
  // The last commits' durable acks, once a checkpoint (time-triggered
  // within about a second) has synced them.
  impl->committer.drain(std::chrono::seconds(3));
  return End::stopped;
}

}  // namespace ambdiag::server
