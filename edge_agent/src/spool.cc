#include "ambdiag/edge_agent/spool.h"

#include <cstring>
#include <stdexcept>

#include "ambdiag/core/checksum.h"
#include "ambdiag/core/error.h"
#include "ambdiag/core/io_util.h"

namespace ambdiag::agent {
namespace {

namespace fs = std::filesystem;

// Spool file: magic, seq, first_frame, n_frames, checksum, then the payload.
constexpr char kMagic[8] = {'A', 'M', 'B', 'S', 'P', 'L', '1', '\0'};
constexpr size_t kHeaderBytes = 8 + 8 + 8 + 4 + 8;

// A folder name from a run id ("P-101/2026-11-21T10:00:00Z"): keep safe
// characters, replace the rest, add the FNV hash so distinct ids stay distinct.
std::string folder_name(const std::string& run_id) {
  std::string s;
  for (char c : run_id) s += (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_') ? c : '_';
  char hash[17];
  std::snprintf(hash, sizeof hash, "%016llx",
                static_cast<unsigned long long>(fnv1a64(run_id.data(), run_id.size())));
  return s.substr(0, 80) + "-" + hash;
}

template <class T>
void append(std::string& out, T v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof v);
}
template <class T>
T take(const std::string& in, size_t& pos) {
  T v;
  std::memcpy(&v, in.data() + pos, sizeof v);
  pos += sizeof v;
  return v;
}

}  // namespace

Spool::Spool(const fs::path& dir, const std::string& run_id, uint64_t limit_bytes, size_t memory_blocks)
    : run_dir_(dir / folder_name(run_id)), limit_bytes_(limit_bytes), memory_limit_(memory_blocks) {
  fs::create_directories(run_dir_);
  // Files left by an earlier, killed agent for this run are stale: this
  // agent produces the run again from its source.
  for (const auto& e : fs::directory_iterator(run_dir_)) fs::remove(e.path());
}

Spool::~Spool() {
  std::error_code ec;
  for (const auto& [seq, size] : on_disk_) fs::remove(file_of(seq), ec);
  fs::remove(run_dir_, ec);  // only succeeds when empty
}

fs::path Spool::file_of(int64_t seq) const { return run_dir_ / (std::to_string(seq) + ".blk"); }

bool Spool::has_room(size_t payload_bytes) const {
  return memory_.size() < memory_limit_ || disk_bytes_ + kHeaderBytes + payload_bytes <= limit_bytes_;
}

bool Spool::put(const Block& b) {
  if (contains(b.seq)) return true;
  if (memory_.size() < memory_limit_) {
    memory_.emplace(b.seq, b);
    return true;
  }
  const uint64_t size = kHeaderBytes + b.payload.size();
  if (disk_bytes_ + size > limit_bytes_) return false;
  std::string bytes(kMagic, sizeof kMagic);
  append(bytes, b.seq);
  append(bytes, b.first_frame);
  append(bytes, b.n_frames);
  append(bytes, b.checksum);
  bytes += b.payload;
  write_file_atomic(file_of(b.seq).string(), bytes);
  on_disk_.emplace(b.seq, size);
  disk_bytes_ += size;
  return true;
}

Block Spool::get(int64_t seq) const {
  if (auto it = memory_.find(seq); it != memory_.end()) return it->second;
  if (!on_disk_.count(seq)) throw std::logic_error("spool: block " + std::to_string(seq) + " not stored");
  const std::string path = file_of(seq).string();
  const std::string bytes = read_file_bytes(path);
  if (bytes.size() < kHeaderBytes || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
    throw std::runtime_error(path + ": damaged spool file (bad header)");
  size_t pos = sizeof kMagic;
  Block b;
  b.seq = take<int64_t>(bytes, pos);
  b.first_frame = take<int64_t>(bytes, pos);
  b.n_frames = take<uint32_t>(bytes, pos);
  b.checksum = take<uint64_t>(bytes, pos);
  b.payload = bytes.substr(pos);
  if (b.seq != seq || fnv1a64(b.payload.data(), b.payload.size()) != b.checksum)
    throw std::runtime_error(path + ": damaged spool file (checksum)");
  return b;
}

void Spool::erase(int64_t seq) {
  if (memory_.erase(seq)) return;
  if (auto it = on_disk_.find(seq); it != on_disk_.end()) {
    std::error_code ec;
    fs::remove(file_of(seq), ec);
    disk_bytes_ -= it->second;
    on_disk_.erase(it);
  }
}

}  // namespace ambdiag::agent
