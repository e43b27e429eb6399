// Store-and-forward buffer of one run's unacknowledged blocks.
//
// The first `memory_blocks` blocks stay in memory; further ones go to files
// in `dir` (one per block, written to a temporary name and renamed, checksum
// verified when read back), up to `limit_bytes` on disk. A block leaves the
// spool when the server acknowledges it as committed. put() refuses a block
// when the disk part is full; the caller then pauses its source and reports
// the spool full in its status.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <set>
#include <string>

#include "ambdiag/edge_agent/block.h"

namespace ambdiag::agent {

class Spool {
 public:
  // `dir` is created if missing; the run gets its own sub-folder, removed
  // when the spool is destroyed empty.
  Spool(const std::filesystem::path& dir, const std::string& run_id, uint64_t limit_bytes, size_t memory_blocks);
  ~Spool();
  Spool(const Spool&) = delete;
  Spool& operator=(const Spool&) = delete;

  // Stores the block; false (nothing stored) if it does not fit.
  bool put(const Block& b);
  // Would a block of this payload size be accepted now?
  bool has_room(size_t payload_bytes) const;
  // The stored block; throws std::runtime_error if a spool file is damaged.
  Block get(int64_t seq) const;
  bool contains(int64_t seq) const { return memory_.count(seq) > 0 || on_disk_.count(seq) > 0; }
  void erase(int64_t seq);

  size_t size() const { return memory_.size() + on_disk_.size(); }
  size_t memory_blocks() const { return memory_.size(); }
  uint64_t disk_bytes() const { return disk_bytes_; }
  uint64_t limit_bytes() const { return limit_bytes_; }

 private:
  std::filesystem::path file_of(int64_t seq) const;

  std::filesystem::path run_dir_;
  uint64_t limit_bytes_;
  size_t memory_limit_;
  std::map<int64_t, Block> memory_;
  std::map<int64_t, uint64_t> on_disk_;  // seq -> file size
  uint64_t disk_bytes_ = 0;
};

}  // namespace ambdiag::agent
