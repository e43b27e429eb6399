// Streams one run to the server and waits until every block is committed.
//
// Protocol (docs/streaming.md): header (transient-local), blocks with at
// most `window_blocks` unacknowledged in flight, the server acknowledges
// committed ranges, then (1.2) durable ones; once every block is
// acknowledged the agent sends the run end (count and checksum) and waits
// for the server's verdict (complete or incomplete). Blocks stay in the
// Spool until acknowledged durable; a server that appears (a restart, which
// may follow a power cut) gets every block not yet durable again. When no server
// is matched the source keeps producing into the spool (disk once memory is
// used up) and the backlog is re-sent from the first unacknowledged block
// when a server appears or acks stall. The server stores (run_id, seq)
// idempotently, so re-sending never duplicates.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

#include "ambdiag/core/checksum.h"
#include "ambdiag/edge_agent/block_source.h"
#include "ambdiag/edge_agent/spool.h"
#include "ambdiag/proto/stream.h"

namespace ambdiag::agent {

struct StreamOptions {
  bool paced = true;                                 // at the recording's sample rate
  size_t window_blocks = 128;                        // sent, not yet acknowledged
  // Checksums of new runs: XXH64 (protocol 1.1, needs a 1.1 server) or
  // FNV-1a 64 (what a 1.0 server verifies). Runs recovered from the spool
  // keep the kind they were spooled with.
  ChecksumKind checksum_kind = ChecksumKind::xxh64;
  // The protocol minor spoken (1.2: durable acks). With a 1.2 server a block
  // leaves the spool when acknowledged durable; acks of what is committed
  // only move the window. Speaking 1.1, or to a 1.1 server, any ack deletes.
  uint32_t protocol_minor = ambdiag_stream_kProtocolMinor;
  std::chrono::milliseconds retransmit_after{2000};  // no ack progress -> resend backlog
  std::chrono::milliseconds heartbeat{250};
  std::chrono::milliseconds timeout{60000};          // no progress at all -> give up
  std::function<bool()> stop_requested;              // e.g. SIGINT; the run is ended as aborted
};

struct StreamResult {
  bool complete = false;  // the server verified count and checksum
  bool server_verdict = false;  // the server answered (complete or not); the spool was removed
  std::string message;    // the server's verdict or why the agent gave up
  int64_t n_blocks = 0;
  int64_t total_frames = 0;
  uint64_t checksum = 0;
  int64_t blocks_sent = 0;  // including re-sent ones
  int64_t resends = 0;      // times the backlog was re-sent
  int64_t blocks_durable = 0;  // blocks the server acknowledged as durable (1.2), or as stored (1.1)
  uint64_t max_spool_disk_bytes = 0;
};

StreamResult stream_run(stream::AgentEndpoints& ep, RecordingSource& source, Spool& spool, const std::string& pump_id,
                        const StreamOptions& opt);

// Sends a run an earlier agent left in `spool` (Spool::recover): its header,
// the blocks still held and its end (aborted if the source was cut off
// before the end), then removes the spool once the server has given its verdict.
StreamResult forward_spooled(stream::AgentEndpoints& ep, Spool& spool, const StreamOptions& opt);

}  // namespace ambdiag::agent
