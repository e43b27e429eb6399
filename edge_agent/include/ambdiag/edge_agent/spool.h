// Store-and-forward buffer of one run, durable across agent restarts.
//
// A run's folder in `dir` holds header.json (the run header, written to a
// temporary name, fsynced and renamed), the blocks in append-only segment
// files seg-NNNNNN.log (each record framed by a length and two checksums, so
// a torn last record is detected and dropped, never forwarded) and, once the
// source has produced everything, end.json (count and checksum, atomic like
// the header). Every block goes to disk; up to `memory_blocks` unacknowledged
// blocks are also kept in memory so sending does not read them back. A block
// leaves the spool when the server acknowledges it as durable (protocol 1.2;
// a 1.1 server: as committed); a segment
// whose blocks are all acknowledged is deleted, and the folder when the
// server gave its verdict on the whole run (remove()). put() refuses a block
// when the segments on disk, of this run and of the runs left in the same
// folder by earlier agents, would exceed `limit_bytes`; the caller then
// pauses its source and reports the spool full in its status. The folder's
// other runs are measured when the spool is made: one agent holds a folder
// (SpoolLock) and works on one run at a time, so they do not grow meanwhile.
//
// A restarted agent lists the folders left behind (pending_runs) and opens
// each with recover(), which reads the header, the end if any and every
// intact block, and reports what it dropped.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "ambdiag/core/checksum.h"
#include "ambdiag/core/process_lock.h"
#include "ambdiag/edge_agent/block.h"

namespace ambdiag::agent {

// What the run header message carries (header.json).
struct SpooledHeader {
  std::string run_id;
  std::string pump_id;
  std::string header_json;  // run.json text without samples
  uint32_t n_channels = 0;
  double sample_rate_hz = 0.0;
  uint32_t frames_per_block = 0;
  // How the blocks' and the run's checksums are computed (core/checksum.h);
  // header.json without it (spools of earlier agents): FNV-1a 64.
  ChecksumKind checksum_kind = ChecksumKind::xxh64;
};

// What the run end carries (end.json), written when the source is done.
struct SpooledEnd {
  int64_t n_blocks = 0;
  int64_t total_frames = 0;
  uint64_t checksum = 0;  // of the whole run, of the header's checksum_kind
};

// One agent process per spool folder: an advisory lock (flock) on
// DIR/agent.lock, held while the owner lives and dropped by the kernel when
// the process ends, also by kill -9. Two agents sharing a folder would
// forward, and then delete, each other's runs.
class SpoolLock {
 public:
  // Creates `dir` if missing. Throws InputError naming the folder and the
  // holder's pid (written into the lock file) if another process holds it.
  explicit SpoolLock(const std::filesystem::path& dir);

 private:
  ProcessLock lock_;
};

class Spool {
 public:
  // A new run: `dir` is created if missing; files an earlier agent left for
  // the same run id are removed (the source produces the run again).
  Spool(const std::filesystem::path& dir, const std::string& run_id, uint64_t limit_bytes, size_t memory_blocks);
  ~Spool();
  Spool(const Spool&) = delete;
  Spool& operator=(const Spool&) = delete;

  // Run folders under `dir` left by an earlier agent (empty if none).
  static std::vector<std::filesystem::path> pending_runs(const std::filesystem::path& dir);
  // Opens a folder left by an earlier agent. Damaged or torn records are
  // dropped (a truncated tail is cut off the file) and described in
  // `problems`; throws InputError if header.json is missing or unreadable.
  static std::unique_ptr<Spool> recover(const std::filesystem::path& run_dir, uint64_t limit_bytes,
                                        size_t memory_blocks, std::vector<std::string>& problems);

  void write_header(const SpooledHeader& h);
  void write_end(const SpooledEnd& e);
  const std::optional<SpooledHeader>& header() const { return header_; }
  // The checksum kind of the blocks held (the header's; the default before one is written).
  ChecksumKind checksum_kind() const { return header_ ? header_->checksum_kind : SpooledHeader{}.checksum_kind; }
  const std::optional<SpooledEnd>& end() const { return end_; }

  // Stores the block; false (nothing stored, `b` untouched) if it does not
  // fit. The rvalue form moves the payload into the memory cache.
  bool put(const Block& b);
  bool put(Block&& b);
  // Would a block of this payload size be accepted now?
  bool has_room(size_t payload_bytes) const;
  // The stored block; throws std::runtime_error if its record is damaged.
  Block get(int64_t seq) const;
  // The block if it is in the memory cache (no copy, no disk read), else null;
  // valid until the next put/erase.
  const Block* peek(int64_t seq) const;
  bool contains(int64_t seq) const { return index_.count(seq) > 0; }
  void erase(int64_t seq);
  // Sequence numbers held, ascending.
  std::vector<int64_t> seqs() const;
  // fsync the open segment (put() does it at most every 100 ms by itself).
  void sync();
  // The server has every block and gave its verdict: delete the folder.
  void remove();

  size_t size() const { return index_.size(); }
  size_t memory_blocks() const { return memory_.size(); }
  uint64_t disk_bytes() const { return disk_bytes_; }  // this run's segments
  // Segments on disk in the whole folder (this run's and the others'): what
  // `limit_bytes` bounds.
  uint64_t folder_disk_bytes() const { return disk_bytes_ + others_bytes_; }
  uint64_t limit_bytes() const { return limit_bytes_; }
  const std::filesystem::path& folder() const { return run_dir_; }

 private:
  struct Where {
    int64_t segment;
    uint64_t offset;  // of the record in its segment
    uint32_t payload_bytes;
  };
  struct Segment {
    uint64_t bytes = 0;
    int64_t live = 0;  // blocks not yet acknowledged
  };
  Spool(std::filesystem::path run_dir, uint64_t limit_bytes, size_t memory_blocks);
  void append(const Block& b);  // the record to the open segment, indexed
  std::filesystem::path segment_path(int64_t segment) const;
  void open_segment(int64_t segment);
  void close_segment();
  void drop_segment(int64_t segment);

  std::filesystem::path run_dir_;
  uint64_t limit_bytes_;
  size_t memory_limit_;
  uint64_t segment_limit_;
  std::optional<SpooledHeader> header_;
  std::optional<SpooledEnd> end_;
  std::map<int64_t, Block> memory_;
  std::map<int64_t, Where> index_;
  std::map<int64_t, Segment> segments_;
  int64_t current_ = -1;  // segment open for appending
  int64_t next_segment_ = 0;
  int fd_ = -1;
  bool dirty_ = false;
  std::chrono::steady_clock::time_point last_sync_{};
  uint64_t disk_bytes_ = 0;
  uint64_t others_bytes_ = 0;  // segments of the other runs in the folder
};

}  // namespace ambdiag::agent
