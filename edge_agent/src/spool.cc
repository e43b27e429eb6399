#include "ambdiag/edge_agent/spool.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "ambdiag/core/checksum.h"
#include "ambdiag/core/error.h"
#include "ambdiag/core/io_util.h"

namespace ambdiag::agent {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// Record: magic, payload length, seq, first_frame, n_frames, reserved,
// payload checksum, checksum of these 40 bytes; then the payload. The header
// checksum makes the length trustworthy, so a damaged payload can be skipped
// and a record running past the end of the file is known to be torn.
constexpr uint32_t kMagic = 0x314b4241;  // "ABK1"
constexpr size_t kRecordHeader = 48;
constexpr auto kSyncInterval = std::chrono::milliseconds(100);

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
void put_le(char* out, size_t& pos, T v) {
  std::memcpy(out + pos, &v, sizeof v);
  pos += sizeof v;
}
template <class T>
T get_le(const char* in, size_t& pos) {
  T v;
  std::memcpy(&v, in + pos, sizeof v);
  pos += sizeof v;
  return v;
}

void write_all(int fd, const char* p, size_t n, const fs::path& path) {
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w < 0) throw std::runtime_error(path.string() + ": spool write failed (" + std::strerror(errno) + ")");
    p += w;
    n -= static_cast<size_t>(w);
  }
}

std::string hex(uint64_t v) {
  char b[17];
  std::snprintf(b, sizeof b, "%016llx", static_cast<unsigned long long>(v));
  return b;
}

}  // namespace

SpoolLock::SpoolLock(const fs::path& dir)
    : lock_((fs::create_directories(dir), (dir / "agent.lock").string()), "spool folder " + dir.string(), "ambdiag-agent",
            "; give each agent a folder of its own") {}

Spool::Spool(fs::path run_dir, uint64_t limit_bytes, size_t memory_blocks)
    : run_dir_(std::move(run_dir)),
      limit_bytes_(limit_bytes),
      memory_limit_(memory_blocks),
      // Segments of about an eighth of the limit: acknowledged blocks free
      // their disk space soon, without a file per block.
      segment_limit_(std::clamp<uint64_t>(limit_bytes / 8, 64 << 10, 64 << 20)) {}

Spool::Spool(const fs::path& dir, const std::string& run_id, uint64_t limit_bytes, size_t memory_blocks)
    : Spool(dir / folder_name(run_id), limit_bytes, memory_blocks) {
  fs::create_directories(run_dir_);
  for (const auto& e : fs::directory_iterator(run_dir_)) fs::remove(e.path());
  // The segments other runs left in the folder count against the limit too.
  for (const auto& run : pending_runs(dir)) {
    if (run == run_dir_) continue;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(run, ec))
      if (e.path().extension() == ".log" && e.is_regular_file(ec)) others_bytes_ += e.file_size(ec);
  }
}

Spool::~Spool() { close_segment(); }

fs::path Spool::segment_path(int64_t segment) const {
  char name[32];
  std::snprintf(name, sizeof name, "seg-%06lld.log", static_cast<long long>(segment));
  return run_dir_ / name;
}

void Spool::open_segment(int64_t segment) {
  close_segment();
  const fs::path p = segment_path(segment);
  fd_ = ::open(p.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd_ < 0) throw std::runtime_error(p.string() + ": cannot create spool segment (" + std::strerror(errno) + ")");
  // The new name must survive a crash too.
  if (const int d = ::open(run_dir_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); d >= 0) {
    ::fsync(d);
    ::close(d);
  }
  current_ = segment;
  segments_[segment];
}

void Spool::close_segment() {
  if (fd_ < 0) return;
  if (dirty_) ::fsync(fd_);
  ::close(fd_);
  fd_ = -1;
  dirty_ = false;
}

void Spool::sync() {
  if (fd_ >= 0 && dirty_ && ::fsync(fd_) != 0)
    throw std::runtime_error(segment_path(current_).string() + ": fsync failed (" + std::strerror(errno) + ")");
  dirty_ = false;
  last_sync_ = Clock::now();
}

void Spool::drop_segment(int64_t segment) {
  auto it = segments_.find(segment);
  if (it == segments_.end()) return;
  if (segment == current_) close_segment(), current_ = -1;
  std::error_code ec;
  fs::remove(segment_path(segment), ec);
  disk_bytes_ -= it->second.bytes;
  segments_.erase(it);
}

void Spool::write_header(const SpooledHeader& h) {
  const nlohmann::json j = {{"format", "ambdiag-spool-1"},    {"run_id", h.run_id},
                            {"pump_id", h.pump_id},           {"header_json", h.header_json},
                            {"n_channels", h.n_channels},     {"sample_rate_hz", h.sample_rate_hz},
                            {"frames_per_block", h.frames_per_block}, {"checksum_kind", to_string(h.checksum_kind)}};
  write_file_atomic((run_dir_ / "header.json").string(), j.dump());
  header_ = h;
}

void Spool::write_end(const SpooledEnd& e) {
  sync();  // the blocks before the end that counts them
  const nlohmann::json j = {
      {"n_blocks", e.n_blocks}, {"total_frames", e.total_frames}, {"checksum", hex(e.checksum)}};
  write_file_atomic((run_dir_ / "end.json").string(), j.dump());
  end_ = e;
}

bool Spool::has_room(size_t payload_bytes) const {
  return folder_disk_bytes() + kRecordHeader + payload_bytes <= limit_bytes_;
}

bool Spool::put(const Block& b) {
  if (contains(b.seq)) return true;
  if (!has_room(b.payload.size())) return false;
  append(b);
  if (memory_.size() < memory_limit_) memory_.emplace(b.seq, b);
  return true;
}

bool Spool::put(Block&& b) {
  if (contains(b.seq)) return true;
  if (!has_room(b.payload.size())) return false;
  append(b);
  if (memory_.size() < memory_limit_) memory_.emplace(b.seq, std::move(b));
  return true;
}

const Block* Spool::peek(int64_t seq) const {
  const auto it = memory_.find(seq);
  return it == memory_.end() ? nullptr : &it->second;
}

void Spool::append(const Block& b) {
  if (current_ < 0 || segments_[current_].bytes >= segment_limit_)
    open_segment(next_segment_++);
  char head[kRecordHeader];
  size_t pos = 0;
  put_le<uint32_t>(head, pos, kMagic);
  put_le<uint32_t>(head, pos, static_cast<uint32_t>(b.payload.size()));
  put_le<int64_t>(head, pos, b.seq);
  put_le<int64_t>(head, pos, b.first_frame);
  put_le<uint32_t>(head, pos, b.n_frames);
  put_le<uint32_t>(head, pos, 0);
  put_le<uint64_t>(head, pos, b.checksum);
  put_le<uint64_t>(head, pos, fnv1a64(head, pos));
  const fs::path path = segment_path(current_);
  write_all(fd_, head, sizeof head, path);
  write_all(fd_, b.payload.data(), b.payload.size(), path);
  dirty_ = true;
  Segment& seg = segments_[current_];
  index_[b.seq] = Where{current_, seg.bytes, static_cast<uint32_t>(b.payload.size())};
  seg.bytes += kRecordHeader + b.payload.size();
  ++seg.live;
  disk_bytes_ += kRecordHeader + b.payload.size();
  if (Clock::now() - last_sync_ >= kSyncInterval) sync();
}

Block Spool::get(int64_t seq) const {
  if (auto it = memory_.find(seq); it != memory_.end()) return it->second;
  const auto w = index_.find(seq);
  if (w == index_.end()) throw std::logic_error("spool: block " + std::to_string(seq) + " not stored");
  const fs::path path = segment_path(w->second.segment);
  std::string bytes(kRecordHeader + w->second.payload_bytes, '\0');
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  const ssize_t n = fd < 0 ? -1 : ::pread(fd, bytes.data(), bytes.size(), static_cast<off_t>(w->second.offset));
  if (fd >= 0) ::close(fd);
  if (n != static_cast<ssize_t>(bytes.size()))
    throw std::runtime_error(path.string() + ": cannot read spooled block " + std::to_string(seq));
  size_t pos = 8;
  Block b;
  b.seq = get_le<int64_t>(bytes.data(), pos);
  b.first_frame = get_le<int64_t>(bytes.data(), pos);
  b.n_frames = get_le<uint32_t>(bytes.data(), pos);
  pos += 4;
  b.checksum = get_le<uint64_t>(bytes.data(), pos);
  b.payload = bytes.substr(kRecordHeader);
  if (b.seq != seq || block_checksum(checksum_kind(), b.payload.data(), b.payload.size()) != b.checksum)
    throw std::runtime_error(path.string() + ": damaged spool record (block " + std::to_string(seq) + ", checksum)");
  return b;
}

void Spool::erase(int64_t seq) {
  memory_.erase(seq);
  const auto w = index_.find(seq);
  if (w == index_.end()) return;
  const int64_t segment = w->second.segment;
  index_.erase(w);
  // A segment whose blocks are all acknowledged is deleted (the open one
  // too: the next block starts a new segment).
  if (--segments_[segment].live == 0) drop_segment(segment);
}

std::vector<int64_t> Spool::seqs() const {
  std::vector<int64_t> out;
  out.reserve(index_.size());
  for (const auto& [seq, w] : index_) out.push_back(seq);
  return out;
}

void Spool::remove() {
  close_segment();
  std::error_code ec;
  fs::remove_all(run_dir_, ec);
  memory_.clear();
  index_.clear();
  segments_.clear();
  current_ = -1;
  disk_bytes_ = 0;
}

std::vector<fs::path> Spool::pending_runs(const fs::path& dir) {
  std::vector<fs::path> out;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return out;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_directory()) out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

std::unique_ptr<Spool> Spool::recover(const fs::path& run_dir, uint64_t limit_bytes, size_t memory_blocks,
                                      std::vector<std::string>& problems) {
  std::unique_ptr<Spool> s(new Spool(run_dir, limit_bytes, memory_blocks));
  const fs::path hp = run_dir / "header.json";
  if (!fs::exists(hp)) throw InputError(run_dir.string() + ": spooled run without header.json (cannot be forwarded)");
  try {
    const auto j = nlohmann::json::parse(read_file_bytes(hp.string()));
    if (j.at("format") != "ambdiag-spool-1") throw InputError("unknown format " + j.at("format").dump());
    s->header_ = SpooledHeader{j.at("run_id"),         j.at("pump_id"),        j.at("header_json"),
                               j.at("n_channels"),     j.at("sample_rate_hz"), j.at("frames_per_block"),
                               ChecksumKind::fnv1a64};
    if (j.contains("checksum_kind")) {
      const auto kind = checksum_kind_from(j.at("checksum_kind").get<std::string>());
      if (!kind) throw InputError("unknown checksum_kind " + j.at("checksum_kind").dump());
      s->header_->checksum_kind = *kind;
    }
    if (fs::exists(run_dir / "end.json")) {
      const auto e = nlohmann::json::parse(read_file_bytes((run_dir / "end.json").string()));
      s->end_ = SpooledEnd{e.at("n_blocks"), e.at("total_frames"),
                           std::stoull(e.at("checksum").get<std::string>(), nullptr, 16)};
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError(run_dir.string() + ": damaged spool header or end: " + e.what());
  } catch (const std::logic_error& e) {  // stoull
    throw InputError(run_dir.string() + ": damaged spool end.json: " + e.what());
  }

  for (const auto& e : fs::directory_iterator(run_dir)) {
    const std::string name = e.path().filename().string();
    if (name.ends_with(".tmp") || name.find(".tmp.") != std::string::npos) {  // a rename that never happened
      fs::remove(e.path());
      continue;
    }
    if (!name.starts_with("seg-") || !name.ends_with(".log")) continue;
    const std::string digits = name.substr(4, name.size() - 8);
    if (digits.empty() || digits.size() > 12 || digits.find_first_not_of("0123456789") != std::string::npos) {
      problems.push_back(e.path().string() + ": not a spool segment name: ignored");
      continue;
    }
    const int64_t segment = std::stoll(digits);
    s->next_segment_ = std::max(s->next_segment_, segment + 1);
    const std::string bytes = read_file_bytes(e.path().string());
    Segment& seg = s->segments_[segment];
    uint64_t pos = 0;
    while (pos < bytes.size()) {
      const std::string where = e.path().string() + " at byte " + std::to_string(pos);
      if (bytes.size() - pos < kRecordHeader) {
        problems.push_back(where + ": torn block record (" + std::to_string(bytes.size() - pos) +
                           " bytes of a header): dropped");
        break;
      }
      size_t p = 0;
      const char* h = bytes.data() + pos;
      const uint32_t magic = get_le<uint32_t>(h, p);
      const uint32_t len = get_le<uint32_t>(h, p);
      size_t q = 40;
      if (magic != kMagic || get_le<uint64_t>(h, q) != fnv1a64(h, 40)) {
        problems.push_back(where + ": damaged block record header: it and the rest of the file dropped");
        break;
      }
      if (bytes.size() - pos - kRecordHeader < len) {
        problems.push_back(where + ": torn block record (" + std::to_string(bytes.size() - pos - kRecordHeader) +
                           " of " + std::to_string(len) + " payload bytes): dropped");
        break;
      }
      Block b;
      b.seq = get_le<int64_t>(h, p);
      b.first_frame = get_le<int64_t>(h, p);
      b.n_frames = get_le<uint32_t>(h, p);
      p += 4;
      b.checksum = get_le<uint64_t>(h, p);
      if (block_checksum(s->checksum_kind(), h + kRecordHeader, len) != b.checksum || b.seq < 0 ||
          s->index_.count(b.seq)) {
        problems.push_back(where + ": block " + std::to_string(b.seq) + " damaged (checksum) or repeated: dropped");
      } else {
        s->index_[b.seq] = Where{segment, pos, len};
        ++seg.live;
      }
      pos += kRecordHeader + len;
    }
    // Cut what was dropped at the end, so the file holds only whole records.
    if (pos < bytes.size()) fs::resize_file(e.path(), pos);
    seg.bytes = std::min<uint64_t>(pos, bytes.size());
    s->disk_bytes_ += seg.bytes;
  }
  return s;
}

}  // namespace ambdiag::agent
