#include "ambdiag/storage/recording_io.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <vector>

#include "ambdiag/core/checksum.h"
#include "ambdiag/core/error.h"
#include "ambdiag/core/io_util.h"
#include "ambdiag/core/run_recording.h"

namespace ambdiag::storage {

namespace fs = std::filesystem;

ImportResult import_recording(Historian& h, const std::string& run_dir, std::size_t chunk_bytes,
                              std::size_t chunks_per_transaction) {
  const RunRecording rec = read_run(run_dir);  // checks everything, samples included
  const std::string json_path = (fs::path(run_dir) / "run.json").string();
  const RunHeader header = run_header_from_json(read_file_bytes(json_path), json_path);

  const auto* bytes = reinterpret_cast<const std::uint8_t*>(rec.samples.data());
  static_assert(std::endian::native == std::endian::little, "samples.f32 is little-endian");
  const std::size_t frame_bytes = rec.channels.size() * sizeof(float);
  const std::int64_t frames_per_chunk = static_cast<std::int64_t>(std::max<std::size_t>(1, chunk_bytes / frame_bytes));
  const std::int64_t n_frames = rec.frame_count();

  h.begin_run(header);
  ImportResult result;
  result.run_id = header.run_id;
  std::vector<Chunk> batch;
  std::int64_t seq = 0;
  for (std::int64_t first = 0; first < n_frames; first += frames_per_chunk, ++seq) {
    const std::int64_t n = std::min(frames_per_chunk, n_frames - first);
    batch.push_back({seq, first, n,
                     {bytes + static_cast<std::size_t>(first) * frame_bytes, static_cast<std::size_t>(n) * frame_bytes}});
    if (batch.size() == chunks_per_transaction || first + n == n_frames) {
      const PutResult put = h.put_chunks(header.run_id, batch);
      result.chunks += put.stored + put.duplicates;
      result.duplicates += put.duplicates;
      batch.clear();
    }
  }
  result.end = h.end_run(header.run_id, n_frames, fnv1a64(bytes, rec.samples.size() * sizeof(float)));
  return result;
}

namespace {

// Writes a file, streaming, and fsyncs it; throws InputError naming the path.
class SyncedFile {
 public:
  explicit SyncedFile(const std::string& path) : path_(path) {
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd_ < 0) throw InputError(path + ": cannot create (" + std::strerror(errno) + ")");
  }
  SyncedFile(const SyncedFile&) = delete;
  SyncedFile& operator=(const SyncedFile&) = delete;
  ~SyncedFile() {
    if (fd_ >= 0) ::close(fd_);
  }
  void write(const void* data, std::size_t n) {
    const auto* p = static_cast<const char*>(data);
    while (n > 0) {
      const ssize_t k = ::write(fd_, p, n);
      if (k < 0 && errno == EINTR) continue;
      if (k < 0) throw InputError(path_ + ": write failed (" + std::strerror(errno) + ")");
      p += k;
      n -= static_cast<std::size_t>(k);
    }
  }
  void close() {
    const int fd = fd_;
    fd_ = -1;
    if (::fsync(fd) != 0 || ::close(fd) != 0) throw InputError(path_ + ": cannot flush (" + std::strerror(errno) + ")");
  }

 private:
  std::string path_;
  int fd_ = -1;
};

void fsync_dir(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

}  // namespace

void export_recording(Historian& h, const std::string& run_id, const std::string& out_dir, bool allow_incomplete) {
  auto snap = h.snapshot();
  const auto run = h.find_run(run_id);
  if (!run) throw InputError("export: unknown run '" + run_id + "'");
  if (run->status != RunStatus::complete && !allow_incomplete)
    throw InputError("export: run '" + run_id + "' is " + to_string(run->status) +
                     (run->status_reason.empty() ? "" : " (" + run->status_reason + ")") +
                     "; export it anyway with --incomplete");
  const fs::path out = fs::absolute(out_dir).lexically_normal();
  std::error_code ec;
  if (fs::exists(out, ec) && !(fs::is_directory(out, ec) && fs::is_empty(out, ec)))
    throw InputError(out_dir + ": exists and is not an empty folder");
  const fs::path tmp = out.parent_path() / (out.filename().string() + ".tmp." + std::to_string(::getpid()));
  fs::remove_all(tmp, ec);
  if (!fs::create_directories(tmp, ec)) throw InputError(tmp.string() + ": cannot create (" + ec.message() + ")");
  try {
    SyncedFile json((tmp / "run.json").string());
    json.write(run->header_json.data(), run->header_json.size());
    json.close();
    SyncedFile samples((tmp / "samples.f32").string());
    h.stream_samples(run_id, [&](std::span<const std::uint8_t> b) {
      samples.write(b.data(), b.size());
      return true;
    });
    samples.close();
    fsync_dir(tmp);
    if (::rename(tmp.c_str(), out.c_str()) != 0)
      throw InputError(out_dir + ": cannot rename into place (" + std::strerror(errno) + ")");
    fsync_dir(out.parent_path());
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

}  // namespace ambdiag::storage
