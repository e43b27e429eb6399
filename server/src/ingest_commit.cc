#include "ingest_commit.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <span>
#include <thread>

#include "ambdiag/core/error.h"
#include "ambdiag/server/events.h"

namespace ambdiag::server::detail {

namespace {

int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

void log_line(bool verbose, const std::string& msg) {
  if (!verbose) return;
  const std::string line = "ambdiag serve: " + msg + "\n";
  std::fputs(line.c_str(), stderr);
}

void Committer::reject(Staged& st, const std::string& reason, const std::string& run_id, const std::string& what) {
  st.rejected.push_back(reason);
  st.log.push_back("rejected (" + reason + ") run '" + run_id + "': " + what);
}

Committer::Committer(storage::Historian& historian, const IngestOptions& opt, IngestCounters& counters,
                     const dds::Writer<ambdiag_stream_Ack>& ack_writer)
    : h_(historian), opt_(opt), counters_(counters), ack_writer_(ack_writer), durable_acks_([this](const Ack& a) {
        send(a);
      }) {
  if (!durable_acks()) return;
  h_.on_durable([this](uint64_t g) { durable_acks_.durable(g); });
  durable_acks_.durable(h_.durable_generation());  // what was durable before it listened
}

Committer::~Committer() {
  if (durable_acks()) h_.on_durable(nullptr);  // before the acks' thread goes
}

bool Committer::durable_acks() const {
  return opt_.speak_protocol_minor.value_or(ambdiag_stream_kProtocolMinor) >= stream::kDurableAckMinor;
}

void Committer::send(const Ack& a) {
  ambdiag_stream_Ack m{};
  m.protocol_version = stream::protocol_version(opt_.speak_protocol_minor.value_or(ambdiag_stream_kProtocolMinor));
  m.run_id = const_cast<char*>(a.run_id.c_str());
  m.first_seq = a.first;
  m.last_seq = a.last;
  m.state = a.state;
  m.message = const_cast<char*>(a.message.c_str());
  m.durable = a.durable;
  if (!ack_writer_.write(m)) return;
  ++counters_.acks_sent;
  if (a.durable && a.state == ambdiag_stream_ACK_STORED) counters_.blocks_acked_durable += a.last - a.first + 1;
}

std::vector<Committer::Ack> Committer::ack_ranges(const std::string& run_id, std::vector<int64_t> seqs) {
  std::vector<Ack> out;
  std::sort(seqs.begin(), seqs.end());
  for (size_t i = 0; i < seqs.size();) {
    size_t j = i;
    while (j + 1 < seqs.size() && seqs[j + 1] <= seqs[j] + 1) ++j;
    out.push_back({run_id, seqs[i], seqs[j], ambdiag_stream_ACK_STORED, ""});
    i = j + 1;
  }
  return out;
}

Committer::Chain& Committer::chain(Staged& st, const std::string& run_id) {
  auto it = st.chains.find(run_id);
  if (it != st.chains.end()) return it->second;
  const auto held = chains_.find(run_id);
  return st.chains[run_id] = held != chains_.end() ? held->second : Chain{};
}

void Committer::apply(BeginRun& w, Staged& st) {
  try {
    // A header is re-sent after an agent's restart: only the first is news,
    // announced in the same transaction (GET /api/v1/events).
    const bool fresh = !h_.find_run(w.header.run_id);
    h_.begin_run(w.header);
    ++st.headers;
    if (fresh)
      h_.append_event("run.new", w.header.pump_id,
                      event_data({{"run_id", w.header.run_id}, {"pump_id", w.header.pump_id}, {"kind", w.header.kind},
                                  {"started_at", w.header.started_at}, {"status", "receiving"}}));
  } catch (const InputError& e) {
    reject(st, "header", w.header.run_id, e.what());
  }
}

// One put_chunks (a savepoint) for the item; if a block conflicts with one
// already stored, the item is stored block by block to isolate it.
void Committer::apply(Blocks& w, Staged& st) {
  std::vector<storage::Chunk> chunks;
  chunks.reserve(w.blocks.size());
  for (const auto& b : w.blocks) chunks.push_back({b.seq, b.first_frame, b.n_frames, b.bytes});
  std::vector<char> ok(w.blocks.size(), 0);
  auto count = [&](const storage::PutResult& r, std::span<const storage::Chunk> c) {
    st.blocks_stored += r.stored;
    st.blocks_duplicate += r.duplicates;
    if (r.stored > 0)
      for (const auto& x : c) st.bytes_stored += static_cast<int64_t>(x.bytes.size());
  };
  try {
    count(h_.put_chunks(w.run_id, chunks), chunks);
    std::fill(ok.begin(), ok.end(), 1);
  } catch (const InputError&) {
    for (size_t i = 0; i < chunks.size(); ++i) {
      try {
        count(h_.put_chunks(w.run_id, std::span(&chunks[i], 1)), std::span(&chunks[i], 1));
        ok[i] = 1;
      } catch (const InputError& e) {
        reject(st, "conflict", w.run_id, e.what());
      }
    }
  }
  Chain& c = chain(st, w.run_id);
  auto& seqs = st.stored_seqs[w.run_id];
  auto& minor = st.agent_minor.try_emplace(w.run_id, UINT32_MAX).first->second;
  for (const auto& b : w.blocks) minor = std::min(minor, b.protocol_minor);
  for (size_t i = 0; i < w.blocks.size(); ++i) {
    if (!ok[i]) continue;
    const auto& b = w.blocks[i];
    seqs.push_back(b.seq);
    // Stored (or held with the same bytes) right after the chain's end:
    // the chain now covers it.
    if (!b.chained || b.seq != c.next_seq) continue;
    if (b.seq == 0 ? b.run_hash_before == run_checksum_init(b.kind) : b.kind == c.kind && b.run_hash_before == c.hash)
      c = {b.seq + 1, b.run_hash_after, b.kind};
  }
  st.stream_progress = true;
}

void Committer::verdict(Staged& st, const std::string& run_id, const std::string& pump_id,
                        std::optional<storage::RunStatus> before, storage::RunStatus after, const std::string& reason) {
  using storage::RunStatus;
  st.ended[run_id] = true;
  st.stream_progress = true;
  const auto changed = [&](const char* status, const std::string& why) {
    nlohmann::json d = {{"run_id", run_id}, {"pump_id", pump_id}, {"status", status}};
    if (!why.empty()) d["reason"] = why;
    h_.append_event("run.status", pump_id, event_data(d));
  };
  if (after == RunStatus::complete) {
    if (before != RunStatus::complete) {
      ++st.complete;
      st.log.push_back("run " + run_id + ": complete");
      st.completed.push_back(run_id);
      changed("complete", "");
      if (opt_.in_commit_run_complete) {
        try {
          opt_.in_commit_run_complete(h_, run_id);
        } catch (const InputError& e) {
          st.log.push_back("run " + run_id + ": not queued for analysis: " + e.what());
        }
      }
    }
    st.verdicts.push_back({run_id, -1, -1, ambdiag_stream_ACK_COMPLETE, "complete: count and checksum verified"});
  } else {
    if (before == RunStatus::receiving) {
      ++st.incomplete;
      st.log.push_back("run " + run_id + ": incomplete: " + reason);
      changed("incomplete", reason);
    }
    st.verdicts.push_back({run_id, -1, -1, ambdiag_stream_ACK_INCOMPLETE, "incomplete: " + reason});
  }
}

void Committer::apply(EndRun& w, Staged& st) {
  try {
    const auto info = h_.find_run(w.run_id);
    const auto before = info ? std::optional(info->status) : std::nullopt;
    if (w.aborted) {
      const auto after = h_.mark_incomplete(w.run_id, "agent aborted: " + w.reason);
      verdict(st, w.run_id, info ? info->pump_id : "", before, after, "aborted: " + w.reason);
      return;
    }
    const Chain& c = chain(st, w.run_id);
    const storage::EndResult r =
        h_.end_run(w.run_id, w.total_frames, w.checksum, storage::HeldDigest{c.next_seq, c.hash, c.kind}, w.kind);
    if (r.used_digest) ++st.from_digest;
    verdict(st, w.run_id, info ? info->pump_id : "", before, r.status, r.reason);
  } catch (const InputError& e) {
    reject(st, "run_end", w.run_id, e.what());
    st.verdicts.push_back({w.run_id, -1, -1, ambdiag_stream_ACK_REJECTED, e.what()});
  }
}

void Committer::apply(MarkIncomplete& w, Staged& st) {
  try {
    const auto info = h_.find_run(w.run_id);
    // Completed meanwhile (its end was queued before the timeout): nothing to do.
    if (!info || info->status == storage::RunStatus::complete) return;
    verdict(st, w.run_id, info->pump_id, info->status, h_.mark_incomplete(w.run_id, w.reason), w.reason);
  } catch (const InputError& e) {
    log_line(opt_.verbose, "run " + w.run_id + ": " + e.what());
  }
}

void Committer::apply(Monitoring& w, Staged& st) {
  // Validated by the receive thread; one by one so a duplicate key or a
  // refused one does not hold back the others.
  for (const auto& s : w.snapshots) {
    try {
      const auto r = h_.put_monitoring(std::span(&s, 1));
      st.monitoring_stored += r.stored;
      st.monitoring_duplicate += r.duplicates;
    } catch (const InputError& e) {
      reject(st, "monitoring", s.pump_id, e.what());
    }
  }
}

void Committer::commit(std::vector<Work>& batch) {
  if (fenced_) return;
  Staged st;
  try {
    // A deadlock PostgreSQL broke (TransientError) rolled all of it back:
    // the same batch again, from a fresh Staged (what the failed attempt
    // noted was not committed). The items themselves are not changed by
    // apply(), and the chains it reads (chains_) change only after a commit.
    const bool committed = storage::retry_transient([&] {
      st = Staged{};
      auto tx = h_.write_batch();
      // First, in the same transaction: does this process still hold its
      // ingest group? A holder paused past its lease and taken over must not
      // store, and above all not acknowledge, from its stale view (e.g. its
      // runs all look timed out after the pause).
      if (opt_.fence && !opt_.fence(h_)) return false;  // the batch rolls back with tx
      for (auto& w : batch) std::visit([&](auto& item) { apply(item, st); }, w);
      if (opt_.commit_delay.count() > 0) std::this_thread::sleep_for(opt_.commit_delay);
      tx.commit();
      return true;
    });
    if (!committed) {
      fenced_ = true;
      ++counters_.commits_fenced;
      log_line(true, "the ingest group was taken over by another server: this batch is rolled back, nothing of it "
                     "acknowledged; ingest stops here");
      return;
    }
  } catch (const storage::StorageError& e) {
    ++counters_.storage_errors;
    log_line(true, std::string("commit failed, nothing of this batch acknowledged (the agents re-send it): ") +
                       e.what());
    std::this_thread::sleep_for(std::chrono::milliseconds(200));  // a full disk or a lock: do not spin
    return;
  }
  // Committed: now the batch counts, and the agents may drop what it held.
  ++counters_.commits;
  for (auto& [run_id, c] : st.chains) {
    if (st.ended.count(run_id))
      chains_.erase(run_id);
    else if (c.next_seq > 0)  // a run re-sent after its end starts no chain of its own
      chains_[run_id] = c;
  }
  for (const auto& reason : st.rejected) counters_.reject(reason);
  counters_.headers += st.headers;
  counters_.blocks_stored += st.blocks_stored;
  counters_.blocks_duplicate += st.blocks_duplicate;
  counters_.bytes_stored += st.bytes_stored;
  counters_.runs_complete += st.complete;
  counters_.runs_incomplete += st.incomplete;
  counters_.monitoring_stored += st.monitoring_stored;
  counters_.monitoring_duplicate += st.monitoring_duplicate;
  counters_.runs_verified_from_digest += st.from_digest;
  if (st.stream_progress) counters_.last_commit_ns = steady_ns();
  if (!durable_acks()) {  // speaking 1.1: committed is all it says
    for (auto& [run_id, seqs] : st.stored_seqs)
      for (const auto& a : ack_ranges(run_id, std::move(seqs))) send(a);
    for (const auto& v : st.verdicts) send(v);
  } else {
    // A 1.2 agent may move its window on what is committed, and delete from
    // its spool what is durable; a 1.1 agent deletes on any ack, so it gets
    // only the durable one. Verdicts end a run at the agent: durable only.
    const uint64_t generation = h_.commit_generation();
    const bool durable_now = h_.durable_generation() >= generation;  // synchronous = FULL
    std::vector<Ack> later;
    for (auto& [run_id, seqs] : st.stored_seqs) {
      const bool new_agent = st.agent_minor[run_id] >= stream::kDurableAckMinor;
      for (auto& a : ack_ranges(run_id, std::move(seqs))) {
        if (new_agent && !durable_now) send(a);
        a.durable = true;
        later.push_back(std::move(a));
      }
    }
    for (auto v : st.verdicts) {
      v.durable = true;
      later.push_back(std::move(v));
    }
    durable_acks_.hold(generation, std::move(later));
  }
  for (const auto& l : st.log) log_line(opt_.verbose, l);
  // After the commit: whoever analyses the run reads it complete.
  if (opt_.on_run_complete)
    for (const auto& id : st.completed) opt_.on_run_complete(id);
}

}  // namespace ambdiag::server::detail
