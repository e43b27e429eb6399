#include "ambdiag/edge_agent/streamer.h"

#include <algorithm>
#include <cstdio>
#include <optional>
#include <vector>

#include "ambdiag/core/checksum.h"

namespace ambdiag::agent {
namespace {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

int64_t now_unix_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

class RunStream {
 public:
  // A new run from its source: the header goes to the spool first.
  RunStream(stream::AgentEndpoints& ep, RecordingSource& src, Spool& spool, std::string pump_id,
            const StreamOptions& opt)
      : ep_(ep), src_(&src), spool_(spool), opt_(opt), ws_(ep.participant) {
    ws_.attach_data(ep_.ack);
    hdr_ = SpooledHeader{src.run().run_id,
                         std::move(pump_id),
                         run_to_json(src.run()).dump(),
                         static_cast<uint32_t>(src.run().channels.size()),
                         src.run().sample_rate_hz,
                         src.frames_per_block(),
                         opt.checksum_kind};
    checksum_ = run_checksum_init(hdr_.checksum_kind);
    spool_.write_header(hdr_);
  }

  // A run an earlier agent left in the spool: no source; blocks no longer in
  // the spool were acknowledged before (their segment was deleted). Without
  // an end the source was cut off: the run is ended as aborted.
  RunStream(stream::AgentEndpoints& ep, Spool& spool, const StreamOptions& opt)
      : ep_(ep), src_(nullptr), spool_(spool), opt_(opt), ws_(ep.participant), hdr_(*spool.header()) {
    ws_.attach_data(ep_.ack);
    const std::vector<int64_t> held = spool_.seqs();
    produced_ = spool_.end() ? spool_.end()->n_blocks : (held.empty() ? 0 : held.back() + 1);
    acked_.assign(static_cast<size_t>(produced_), 1);
    for (int64_t s : held)
      if (s < produced_) acked_[static_cast<size_t>(s)] = 0;
    for (char a : acked_) acked_count_ += a;
    durable_ = acked_;  // blocks no longer in the spool were acknowledged durable
    durable_count_ = acked_count_;
    while (first_unacked_ < produced_ && acked_[static_cast<size_t>(first_unacked_)]) ++first_unacked_;
    send_cursor_ = first_unacked_;
    source_done_ = true;
    if (spool_.end()) {
      total_frames_ = spool_.end()->total_frames;
      checksum_ = spool_.end()->checksum;
    } else {
      for (int64_t s : held) {
        const Block b = spool_.get(s);
        total_frames_ = std::max(total_frames_, b.first_frame + b.n_frames);
      }
      end_aborted_ = true;
      end_reason_ = "agent restarted before the run's end: source lost after " + std::to_string(total_frames_) +
                    " frames";
    }
  }

  StreamResult run() {
    start_ = Clock::now();
    last_progress_ = last_durable_progress_ = start_;
    send_header();
    while (!final_) {
      const auto now = Clock::now();
      if (now - last_heartbeat_ >= opt_.heartbeat) heartbeat(now);
      take_acks();
      if (final_) break;
      if (opt_.stop_requested && opt_.stop_requested()) {
        abort_run("agent stopped by signal");
        break;
      }
      produce(now);
      detect_server(now);
      send_blocks();
      maybe_send_end(now);
      if (now - last_progress_ > opt_.timeout) {
        give_up();
        break;
      }
      ws_.wait(next_wait(now));
    }
    release_instances();
    // Every block acknowledged and the verdict in: the spool is done.
    if (final_) spool_.remove();
    result_.server_verdict = final_;
    result_.n_blocks = produced_;
    result_.blocks_durable = durable_count_;
    result_.total_frames = total_frames_;
    result_.checksum = checksum_;
    heartbeat(Clock::now(), ambdiag_stream_AGENT_DONE);
    return result_;
  }

 private:
  void send_header() {
    ambdiag_stream_RunHeader h{};
    h.protocol_version = version_;
    h.run_id = const_cast<char*>(hdr_.run_id.c_str());
    h.pump_id = const_cast<char*>(hdr_.pump_id.c_str());
    h.header_json = const_cast<char*>(hdr_.header_json.c_str());
    h.n_channels = hdr_.n_channels;
    h.sample_rate_hz = hdr_.sample_rate_hz;
    h.frames_per_block = hdr_.frames_per_block;
    ep_.header.write(h);
  }

  // The run's header and end stay in the transient-local writers (for a
  // server that restarts mid-run) until the run is over: then release them,
  // so a long-running agent does not replay finished runs to new servers.
  void release_instances() {
    try {
      char empty[] = "";
      ambdiag_stream_RunHeader h{};
      h.run_id = const_cast<char*>(hdr_.run_id.c_str());
      h.pump_id = h.header_json = empty;
      ep_.header.unregister(h);
      if (end_sent_) {
        ambdiag_stream_RunEnd e{};
        e.run_id = const_cast<char*>(hdr_.run_id.c_str());
        e.pump_id = e.reason = empty;
        ep_.end.unregister(e);
      }
    } catch (const dds::DdsError& e) {
      std::fprintf(stderr, "ambdiag-agent: releasing run %s: %s\n", hdr_.run_id.c_str(), e.what());
    }
  }

  void heartbeat(Clock::time_point now, std::optional<ambdiag_stream_AgentState> forced = std::nullopt) {
    last_heartbeat_ = now;
    ambdiag_stream_AgentStatus s{};
    s.protocol_version = version_;
    s.pump_id = const_cast<char*>(hdr_.pump_id.c_str());
    s.run_id = const_cast<char*>(hdr_.run_id.c_str());
    s.spool_bytes = spool_.folder_disk_bytes();
    s.spool_limit_bytes = spool_.limit_bytes();
    s.spool_full = spool_full_;
    s.blocks_pending = produced_ - acked_count_;
    s.time_ns = now_unix_ns();
    s.state = forced ? *forced
              : spool_full_ ? ambdiag_stream_AGENT_SPOOL_FULL
              : matched_ == 0 ? ambdiag_stream_AGENT_SPOOLING
                              : ambdiag_stream_AGENT_STREAMING;
    ep_.status.write(s);
  }

  void take_acks() {
    ep_.ack.take(4096, [&](const ambdiag_stream_Ack& a, const dds_sample_info_t&) {
      if (hdr_.run_id != a.run_id) return;
      if (!stream::compatible(a.protocol_version)) {
        if (!warned_version_)
          std::fprintf(stderr, "ambdiag-agent: server speaks protocol %s, this agent %s: ignoring its acks\n",
                       stream::version_string(a.protocol_version).c_str(),
                       stream::version_string(stream::kProtocolVersion).c_str());
        warned_version_ = true;
        return;
      }
      if (a.state == ambdiag_stream_ACK_STORED) {
        // A 1.2 server's ack without `durable` is only committed: it moves
        // the window; the block stays in the spool until its durable ack.
        // A 1.1 server's acks (or this agent speaking 1.1) delete at once.
        const bool deletes = a.durable || !durable_acks(a.protocol_version);
        for (int64_t s = std::max<int64_t>(a.first_seq, 0); s <= a.last_seq && s < produced_; ++s) {
          const auto i = static_cast<size_t>(s);
          if (!acked_[i]) acked_[i] = 1, ++acked_count_;
          if (!deletes || durable_[i]) continue;
          durable_[i] = 1;
          ++durable_count_;
          last_durable_progress_ = Clock::now();
          spool_.erase(s);
        }
        const int64_t before = first_unacked_;
        while (first_unacked_ < produced_ && acked_[static_cast<size_t>(first_unacked_)]) ++first_unacked_;
        if (first_unacked_ > before) last_progress_ = last_ack_progress_ = Clock::now();
        send_cursor_ = std::max(send_cursor_, first_unacked_);
      } else if (end_sent_) {
        final_ = true;
        result_.complete = a.state == ambdiag_stream_ACK_COMPLETE;
        result_.message = a.message;
      }
    });
  }

  void produce(Clock::time_point now) {
    if (!src_) return;
    const int64_t due = opt_.paced ? static_cast<int64_t>(std::chrono::duration<double>(now - start_).count() *
                                                           hdr_.sample_rate_hz)
                                   : INT64_MAX;
    for (int i = 0; i < 64 && !source_done_; ++i) {
      if (src_->frames_produced() >= due) break;
      // As fast as possible: a file source waits for the server rather than
      // filling the spool, except while no server is there (store-and-forward).
      if (!opt_.paced && matched_ > 0 && produced_ - first_unacked_ >= static_cast<int64_t>(2 * opt_.window_blocks))
        break;
      if (!pending_) pending_ = src_->next();
      if (!pending_) {
        source_done_ = true;
        total_frames_ = src_->frames_produced();
        spool_.write_end(SpooledEnd{produced_, total_frames_, checksum_});
        break;
      }
      // The block's checksum and the run's, in one pass over the payload.
      const BlockChecksums sums =
          block_checksums(hdr_.checksum_kind, pending_->payload.data(), pending_->payload.size(), checksum_);
      pending_->checksum = sums.block;
      if (!spool_.put(std::move(*pending_))) {  // moves only if stored
        if (!spool_full_)
          std::fprintf(stderr, "ambdiag-agent: spool full (%llu of %llu bytes on disk): source paused\n",
                       static_cast<unsigned long long>(spool_.folder_disk_bytes()),
                       static_cast<unsigned long long>(spool_.limit_bytes()));
        spool_full_ = true;
        break;
      }
      if (spool_full_) std::fprintf(stderr, "ambdiag-agent: spool has room again: source resumed\n");
      spool_full_ = false;
      checksum_ = sums.run_after;
      acked_.push_back(0);
      durable_.push_back(0);
      ++produced_;
      pending_.reset();
      last_progress_ = now;
    }
    result_.max_spool_disk_bytes = std::max(result_.max_spool_disk_bytes, spool_.disk_bytes());
  }

  void detect_server(Clock::time_point now) {
    const int32_t m = ep_.block.matched();
    const bool new_server = m > matched_;
    if (m != matched_)
      std::fprintf(stderr, "ambdiag-agent: %s (%d server reader%s matched)\n",
                   m > matched_ ? "server appeared" : "server gone, spooling", m, m == 1 ? "" : "s");
    matched_ = m;
    const bool stalled = send_cursor_ > first_unacked_ && now - last_ack_progress_ > opt_.retransmit_after;
    // Committed but never made durable: the server that committed them may
    // have lost them (a power cut, then a restart). A new server, or no
    // durable ack for a long while, and they are sent again.
    const bool undurable = acked_count_ > durable_count_;
    const bool durable_stalled = undurable && now - last_durable_progress_ > 4 * opt_.retransmit_after;
    if ((new_server || durable_stalled) && undurable && matched_ > 0) {
      forget_undurable();
      last_durable_progress_ = now;
    }
    if ((new_server || stalled || durable_stalled) && matched_ > 0) {
      // Re-send everything not acknowledged (stored idempotently by the server).
      if (send_cursor_ > first_unacked_ || end_sent_) ++result_.resends;
      send_cursor_ = first_unacked_;
      last_ack_progress_ = now;
      send_header();
      if (end_sent_) send_end();
    }
  }

  void send_blocks() {
    if (matched_ == 0) return;
    while (send_cursor_ < produced_ && send_cursor_ - first_unacked_ < static_cast<int64_t>(opt_.window_blocks)) {
      if (acked_[static_cast<size_t>(send_cursor_)]) {
        ++send_cursor_;
        continue;
      }
      // From the memory cache without a copy; from disk otherwise.
      std::optional<Block> from_disk;
      const Block* held = spool_.peek(send_cursor_);
      if (!held) held = &from_disk.emplace(spool_.get(send_cursor_));
      const Block& b = *held;
      ambdiag_stream_SampleBlock s{};
      s.protocol_version = version_;
      s.run_id = const_cast<char*>(hdr_.run_id.c_str());
      s.seq = b.seq;
      s.first_frame = b.first_frame;
      s.n_frames = b.n_frames;
      s.checksum = b.checksum;
      s.payload = stream::borrow_octets(b.payload.data(), b.payload.size());
      s.checksum_kind = static_cast<uint32_t>(hdr_.checksum_kind);
      if (!ep_.block.write(s)) break;  // pushed back: try again next round
      if (send_cursor_ == first_unacked_ || result_.blocks_sent == 0) last_ack_progress_ = Clock::now();
      ++send_cursor_;
      ++result_.blocks_sent;
    }
  }

  // Blocks acknowledged as committed but not as durable count as not
  // acknowledged again; the run end waits until they are committed again.
  void forget_undurable() {
    for (int64_t s = 0; s < produced_; ++s) {
      const auto i = static_cast<size_t>(s);
      if (acked_[i] && !durable_[i]) acked_[i] = 0, --acked_count_;
    }
    first_unacked_ = 0;
    while (first_unacked_ < produced_ && acked_[static_cast<size_t>(first_unacked_)]) ++first_unacked_;
    if (first_unacked_ < produced_) end_sent_ = false;
  }

  // Does the sender of this ack (and this agent) speak durable acks (1.2)?
  bool durable_acks(uint32_t ack_version) const {
    return std::min(stream::protocol_minor(ack_version), opt_.protocol_minor) >= stream::kDurableAckMinor;
  }

  void send_end() { send_end(end_aborted_, end_reason_); }
  void send_end(bool aborted, const std::string& reason) {
    ambdiag_stream_RunEnd e{};
    e.protocol_version = version_;
    e.run_id = const_cast<char*>(hdr_.run_id.c_str());
    e.pump_id = const_cast<char*>(hdr_.pump_id.c_str());
    e.total_frames = src_ ? src_->frames_produced() : total_frames_;
    e.n_blocks = produced_;
    e.checksum = checksum_;
    e.checksum_kind = static_cast<uint32_t>(hdr_.checksum_kind);
    e.aborted = aborted;
    e.reason = const_cast<char*>(reason.c_str());
    ep_.end.write(e);
  }

  void maybe_send_end(Clock::time_point now) {
    if (!source_done_ || first_unacked_ < produced_ || matched_ == 0) return;
    if (!end_sent_ || now - end_sent_at_ > opt_.retransmit_after) {
      send_end();
      end_sent_ = true;
      end_sent_at_ = now;
    }
  }

  void abort_run(const std::string& reason) {
    send_end(true, reason);
    ep_.end.wait_for_acks(2s);
    result_.complete = false;
    result_.message = "aborted: " + reason;
  }

  void give_up() {
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "timeout: no progress for %.0f s; %lld of %lld blocks acknowledged as committed%s%s",
                  std::chrono::duration<double>(opt_.timeout).count(), static_cast<long long>(acked_count_),
                  static_cast<long long>(produced_), matched_ == 0 ? "; no server matched" : "",
                  end_sent_ ? "; run end sent, no verdict from the server" : "");
    result_.complete = false;
    result_.message = buf;
  }

  std::chrono::nanoseconds next_wait(Clock::time_point now) const {
    if (!source_done_ && !opt_.paced && !spool_full_ && (matched_ == 0 || produced_ - first_unacked_ < static_cast<int64_t>(2 * opt_.window_blocks)))
      return 0ns;
    if (matched_ > 0 && send_cursor_ < produced_ && send_cursor_ - first_unacked_ < static_cast<int64_t>(opt_.window_blocks))
      return 0ns;
    (void)now;
    return 5ms;
  }

  stream::AgentEndpoints& ep_;
  RecordingSource* src_;  // null: a run recovered from the spool
  Spool& spool_;
  const StreamOptions& opt_;
  dds::WaitSet ws_;
  SpooledHeader hdr_;
  bool end_aborted_ = false;
  std::string end_reason_;
  int64_t total_frames_ = 0;

  Clock::time_point start_, last_progress_, last_ack_progress_, last_durable_progress_, last_heartbeat_, end_sent_at_;
  const uint32_t version_ = stream::protocol_version(opt_.protocol_minor);
  std::optional<Block> pending_;
  bool source_done_ = false, spool_full_ = false, end_sent_ = false, final_ = false, warned_version_ = false;
  int32_t matched_ = 0;
  int64_t produced_ = 0, first_unacked_ = 0, send_cursor_ = 0, acked_count_ = 0, durable_count_ = 0;
  std::vector<char> acked_;    // committed (flow control)
  std::vector<char> durable_;  // acknowledged durable: gone from the spool
  uint64_t checksum_ = kFnv1a64Init;
  StreamResult result_;
};

}  // namespace

StreamResult stream_run(stream::AgentEndpoints& ep, RecordingSource& source, Spool& spool, const std::string& pump_id,
                        const StreamOptions& opt) {
  RunStream s(ep, source, spool, pump_id, opt);
  return s.run();
}

StreamResult forward_spooled(stream::AgentEndpoints& ep, Spool& spool, const StreamOptions& opt) {
  RunStream s(ep, spool, opt);
  return s.run();
}

}  // namespace ambdiag::agent
