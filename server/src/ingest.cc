#include "ambdiag/server/ingest.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <optional>
#include <span>
#include <thread>
#include <unordered_map>

#include "ambdiag/core/checksum.h"
#include "ambdiag/core/error.h"
#include "ambdiag/proto/stream.h"
#include "ambdiag/storage/historian.h"

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

nlohmann::json IngestCounters::to_json() const {
  nlohmann::json j = {{"headers", headers.load()},
                      {"blocks_received", blocks_received.load()},
                      {"blocks_stored", blocks_stored.load()},
                      {"blocks_duplicate", blocks_duplicate.load()},
                      {"bytes_stored", bytes_stored.load()},
                      {"commits", commits.load()},
                      {"runs_complete", runs_complete.load()},
                      {"runs_incomplete", runs_incomplete.load()},
                      {"blocks_orphan", blocks_orphan.load()},
                      {"acks_sent", acks_sent.load()},
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

struct ActiveRun {
  std::string pump_id;
  uint32_t n_channels = 0;
  Clock::time_point last_seen;
};

struct PendingBlock {
  int64_t seq, first_frame, n_frames;
  std::vector<uint8_t> bytes;
};

bool all_finite(const uint8_t* p, size_t n_bytes) {
  for (size_t i = 0; i + 4 <= n_bytes; i += 4) {
    float f;
    std::memcpy(&f, p + i, 4);
    if (!std::isfinite(f)) return false;
  }
  return true;
}

}  // namespace

struct Ingest::Impl {
  Impl(storage::Historian& h, IngestOptions o, IngestCounters& c)
      : historian(h), opt(std::move(o)), counters(c), ep(opt.domain, opt.partitions), ws(ep.participant) {
    ws.attach_data(ep.header);
    ws.attach_data(ep.block);
    ws.attach_data(ep.end);
    ws.attach_data(ep.status);
  }

  storage::Historian& historian;
  IngestOptions opt;
  IngestCounters& counters;
  stream::ServerEndpoints ep;
  dds::WaitSet ws;
  std::unordered_map<std::string, ActiveRun> active;                // runs receiving, by run_id
  std::unordered_map<std::string, Clock::time_point> pump_seen;     // last heartbeat per pump
  std::unordered_map<std::string, bool> warned_pump_version;

  template <class... A>
  void log(const char* fmt, A... a) {
    if (!opt.verbose) return;
    std::fprintf(stderr, "ambdiag serve: ");
    std::fprintf(stderr, fmt, a...);
    std::fputc('\n', stderr);
  }

  void reject(const std::string& reason, const std::string& run_id, const std::string& what) {
    counters.reject(reason);
    log("rejected (%s) run '%s': %s", reason.c_str(), run_id.c_str(), what.c_str());
  }

  void ack(const std::string& run_id, int64_t first, int64_t last, ambdiag_stream_AckState state,
           const std::string& message) {
    ambdiag_stream_Ack a{};
    a.protocol_version = stream::kProtocolVersion;
    a.run_id = const_cast<char*>(run_id.c_str());
    a.first_seq = first;
    a.last_seq = last;
    a.state = state;
    a.message = const_cast<char*>(message.c_str());
    if (ep.ack.write(a)) ++counters.acks_sent;
  }

  void take_status() {
    ep.status.take(4096, [&](const ambdiag_stream_AgentStatus& s, const dds_sample_info_t&) {
      ++counters.heartbeats;
      if (!stream::compatible(s.protocol_version)) {
        if (!warned_pump_version[s.pump_id])
          reject("version", s.run_id, std::string("agent of pump ") + s.pump_id + " speaks protocol " +
                                          stream::version_string(s.protocol_version) + ", server " +
                                          stream::version_string(stream::kProtocolVersion));
        warned_pump_version[s.pump_id] = true;
        return;
      }
      const auto now = Clock::now();
      pump_seen[s.pump_id] = now;
      if (auto it = active.find(s.run_id); it != active.end() && it->second.pump_id == s.pump_id)
        it->second.last_seen = now;
    });
  }

  void take_headers() {
    ep.header.take(256, [&](const ambdiag_stream_RunHeader& h, const dds_sample_info_t&) {
      const std::string run_id = h.run_id;
      if (!stream::compatible(h.protocol_version)) {
        reject("version", run_id, "protocol " + stream::version_string(h.protocol_version));
        return;
      }
      try {
        const storage::RunHeader rh = storage::run_header_from_json(h.header_json, "run header of " + run_id);
        if (rh.run_id != run_id) throw InputError("run header: run_id '" + rh.run_id + "' differs from the key");
        if (rh.channels.size() != h.n_channels)
          throw InputError("run header: n_channels " + std::to_string(h.n_channels) + " but run.json has " +
                           std::to_string(rh.channels.size()) + " channels");
        if (rh.sample_rate_hz != h.sample_rate_hz) throw InputError("run header: sample_rate_hz differs from run.json");
        historian.begin_run(rh);
        ++counters.headers;
        const bool known = active.count(run_id) > 0;
        active[run_id] = ActiveRun{rh.pump_id, h.n_channels, Clock::now()};
        if (!known) log("run %s of pump %s: receiving", run_id.c_str(), rh.pump_id.c_str());
      } catch (const InputError& e) {
        reject("header", run_id, e.what());
      }
    });
  }

  // A run the historian knows (e.g. after a server restart) becomes active
  // again when its blocks arrive before its header is re-delivered.
  ActiveRun* find_or_load(const std::string& run_id) {
    if (auto it = active.find(run_id); it != active.end()) return &it->second;
    const auto info = historian.find_run(run_id);
    if (!info || info->status == storage::RunStatus::complete) return nullptr;
    auto& r = active[run_id];
    r = ActiveRun{info->pump_id, static_cast<uint32_t>(info->n_channels), Clock::now()};
    return &r;
  }

  // Validates blocks into per-run batches; returns the number taken.
  size_t take_blocks(std::map<std::string, std::vector<PendingBlock>>& batch) {
    return ep.block.take(opt.max_batch_blocks, [&](const ambdiag_stream_SampleBlock& b, const dds_sample_info_t&) {
      ++counters.blocks_received;
      const std::string run_id = b.run_id;
      const size_t n_bytes = b.payload._length;
      if (!stream::compatible(b.protocol_version)) {
        reject("version", run_id, "block protocol " + stream::version_string(b.protocol_version));
        return;
      }
      if (n_bytes > stream::kMaxBlockPayloadBytes) {
        reject("oversized", run_id, "block " + std::to_string(b.seq) + ": payload " + std::to_string(n_bytes) +
                                        " bytes > limit " + std::to_string(stream::kMaxBlockPayloadBytes));
        return;
      }
      const ActiveRun* run = find_or_load(run_id);
      if (!run) {
        ++counters.blocks_orphan;  // header not (yet) seen: the agent re-sends unacknowledged blocks
        return;
      }
      if (b.seq < 0 || b.first_frame < 0 || b.n_frames == 0 ||
          n_bytes != static_cast<size_t>(b.n_frames) * run->n_channels * sizeof(float)) {
        reject("size", run_id, "block " + std::to_string(b.seq) + ": " + std::to_string(n_bytes) + " bytes for " +
                                   std::to_string(b.n_frames) + " frames x " + std::to_string(run->n_channels) +
                                   " channels (seq " + std::to_string(b.seq) + ", first_frame " +
                                   std::to_string(b.first_frame) + ")");
        return;
      }
      if (fnv1a64(b.payload._buffer, n_bytes) != b.checksum) {
        reject("checksum", run_id, "block " + std::to_string(b.seq) + ": checksum mismatch");
        return;
      }
      if (!all_finite(b.payload._buffer, n_bytes)) {
        reject("non_finite", run_id, "block " + std::to_string(b.seq) + ": NaN or infinite sample");
        return;
      }
      batch[run_id].push_back(
          PendingBlock{b.seq, b.first_frame, b.n_frames, std::vector<uint8_t>(b.payload._buffer, b.payload._buffer + n_bytes)});
    });
  }

  // One transaction per run; a conflicting block fails the transaction, so
  // the batch is then stored block by block to isolate it.
  std::vector<int64_t> store(const std::string& run_id, const std::vector<PendingBlock>& blocks) {
    std::vector<storage::Chunk> chunks;
    for (const auto& b : blocks) chunks.push_back(storage::Chunk{b.seq, b.first_frame, b.n_frames, b.bytes});
    std::vector<int64_t> ok;
    auto count = [&](const storage::PutResult& r, size_t bytes) {
      counters.blocks_stored += r.stored;
      counters.blocks_duplicate += r.duplicates;
      if (r.stored > 0) counters.bytes_stored += static_cast<int64_t>(bytes);
      ++counters.commits;
      if (opt.commit_delay.count() > 0) std::this_thread::sleep_for(opt.commit_delay);
    };
    try {
      size_t bytes = 0;
      for (const auto& b : blocks) bytes += b.bytes.size();
      count(historian.put_chunks(run_id, chunks), bytes);
      for (const auto& b : blocks) ok.push_back(b.seq);
    } catch (const InputError&) {
      for (size_t i = 0; i < chunks.size(); ++i) {
        try {
          count(historian.put_chunks(run_id, std::span(&chunks[i], 1)), blocks[i].bytes.size());
          ok.push_back(blocks[i].seq);
        } catch (const InputError& e) {
          reject("conflict", run_id, e.what());
        }
      }
    }
    return ok;
  }

  void ack_ranges(const std::string& run_id, std::vector<int64_t> seqs) {
    std::sort(seqs.begin(), seqs.end());
    for (size_t i = 0; i < seqs.size();) {
      size_t j = i;
      while (j + 1 < seqs.size() && seqs[j + 1] <= seqs[j] + 1) ++j;
      ack(run_id, seqs[i], seqs[j], ambdiag_stream_ACK_STORED, "");
      i = j + 1;
    }
  }

  void take_ends() {
    ep.end.take(256, [&](const ambdiag_stream_RunEnd& e, const dds_sample_info_t&) {
      const std::string run_id = e.run_id;
      if (!stream::compatible(e.protocol_version)) {
        reject("version", run_id, "run end protocol " + stream::version_string(e.protocol_version));
        return;
      }
      try {
        if (e.aborted) {
          const auto st = historian.mark_incomplete(run_id, std::string("agent aborted: ") + e.reason);
          finish(run_id, st, std::string("aborted: ") + e.reason);
          return;
        }
        const storage::EndResult r = historian.end_run(run_id, e.total_frames, e.checksum);
        finish(run_id, r.status, r.reason);
      } catch (const InputError& ex) {
        reject("run_end", run_id, ex.what());
        ack(run_id, -1, -1, ambdiag_stream_ACK_REJECTED, ex.what());
      }
    });
  }

  void finish(const std::string& run_id, storage::RunStatus st, const std::string& reason) {
    const bool was_active = active.erase(run_id) > 0;
    if (st == storage::RunStatus::complete) {
      if (was_active) ++counters.runs_complete, log("run %s: complete", run_id.c_str());
      ack(run_id, -1, -1, ambdiag_stream_ACK_COMPLETE, "complete: count and checksum verified");
    } else {
      if (was_active) ++counters.runs_incomplete, log("run %s: incomplete: %s", run_id.c_str(), reason.c_str());
      ack(run_id, -1, -1, ambdiag_stream_ACK_INCOMPLETE, "incomplete: " + reason);
    }
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
      try {
        finish(run_id, historian.mark_incomplete(run_id, reason), reason);
      } catch (const InputError& e) {
        active.erase(run_id);
        log("run %s: %s", run_id.c_str(), e.what());
      }
    }
  }

  void step() {
    ws.wait(100ms);
    take_status();
    take_headers();
    // Blocks: drain in batches, one transaction per run per batch, acks after commit.
    for (int round = 0; round < 16; ++round) {
      std::map<std::string, std::vector<PendingBlock>> batch;
      const size_t n = take_blocks(batch);
      for (auto& [run_id, blocks] : batch) {
        if (auto it = active.find(run_id); it != active.end()) it->second.last_seen = Clock::now();
        ack_ranges(run_id, store(run_id, blocks));
      }
      if (n < opt.max_batch_blocks) break;
    }
    take_ends();
    check_timeouts();
  }
};

Ingest::Ingest(storage::Historian& historian, IngestOptions opt)
    : impl_(std::make_unique<Impl>(historian, std::move(opt), counters_)) {}

Ingest::~Ingest() = default;

void Ingest::run(const std::atomic<bool>& stop_flag) {
  while (!stop_flag.load()) impl_->step();
}

}  // namespace ambdiag::server
