// bench_storage: historian and REST throughput against the bare SQLite
// ceiling (docs/benchmarks.md, "Historian and REST (issue 5)").
//
//   bench_storage [--mb N] [--dir DIR]
//
// Every figure: wall time and CPU time (user + sys of this process, which
// holds both HTTP client and server in the REST figures).
#include <sqlite3.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>

#include "ambdiag/core/checksum.h"
#include "ambdiag/core/process_memory.h"
#include "ambdiag/server/rest_server.h"
#include "ambdiag/storage/historian.h"
#include "bench_chunks.h"
#include "bench_util.h"

namespace {

namespace fs = std::filesystem;
using ambdiag::storage::Chunk;
using ambdiag::storage::Historian;

using ambdiag::bench::kChannels;
using ambdiag::bench::kChunkBytes;
using ambdiag::bench::kFramesPerChunk;
using ambdiag::bench::run_json;

struct Timer {
  std::chrono::steady_clock::time_point t0 = std::chrono::steady_clock::now();
  double c0 = ambdiag::bench::cpu_seconds();
  double wall() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); }
  double cpu() const { return ambdiag::bench::cpu_seconds() - c0; }
};

void report(const char* what, double bytes, const Timer& t) {
  const double w = t.wall(), c = t.cpu();
  std::printf("%-52s %8.1f MB/s wall %8.1f MB/s per CPU-s  (%.2f s wall, %.2f s CPU)\n", what, bytes / w / 1e6,
              bytes / c / 1e6, w, c);
}

void die(sqlite3* db, int rc, const char* what) {
  if (rc == SQLITE_OK || rc == SQLITE_DONE || rc == SQLITE_ROW) return;
  std::fprintf(stderr, "bench_storage: %s: %s\n", what, db ? sqlite3_errmsg(db) : sqlite3_errstr(rc));
  std::exit(1);
}

// The ceiling: prepared INSERT of the same 32 KiB blobs, batched in
// transactions, same pragmas as the historian, no checks, no counters.
void bare_sqlite(const fs::path& path, const std::vector<std::uint8_t>& data, std::size_t n_chunks, int batch) {
  fs::remove(path);
  sqlite3* db = nullptr;
  die(db, sqlite3_open(path.c_str(), &db), "open");
  die(db,
      sqlite3_exec(db,
                   "PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL; PRAGMA temp_store=MEMORY;"
                   "PRAGMA cache_size=-65536; PRAGMA secure_delete=OFF;"
                   "CREATE TABLE c (run_id TEXT NOT NULL, seq INTEGER NOT NULL, data BLOB NOT NULL,"
                   " PRIMARY KEY (run_id, seq))",
                   nullptr, nullptr, nullptr),
      "schema");
  sqlite3_stmt* ins = nullptr;
  die(db, sqlite3_prepare_v2(db, "INSERT INTO c VALUES (?, ?, ?)", -1, &ins, nullptr), "prepare");
  Timer t;
  for (std::size_t i = 0; i < n_chunks; ++i) {
    if (i % static_cast<std::size_t>(batch) == 0) die(db, sqlite3_exec(db, "BEGIN", nullptr, nullptr, nullptr), "begin");
    sqlite3_bind_text(ins, 1, "P-1/run", -1, SQLITE_STATIC);
    sqlite3_bind_int64(ins, 2, static_cast<sqlite3_int64>(i));
    sqlite3_bind_blob(ins, 3, data.data() + i * kChunkBytes, static_cast<int>(kChunkBytes), SQLITE_STATIC);
    die(db, sqlite3_step(ins), "insert");
    sqlite3_reset(ins);
    if ((i + 1) % static_cast<std::size_t>(batch) == 0 || i + 1 == n_chunks)
      die(db, sqlite3_exec(db, "COMMIT", nullptr, nullptr, nullptr), "commit");
  }
  const std::string label = "bare SQLite insert, " + std::to_string(batch) + " chunks/transaction";
  report(label.c_str(), static_cast<double>(n_chunks * kChunkBytes), t);
  sqlite3_finalize(ins);
  sqlite3_close(db);
}

}  // namespace

int main(int argc, char** argv) {
  ambdiag::retain_freed_memory();
  double mb = 128;
  fs::path dir = fs::temp_directory_path() / "ambdiag-bench-storage";
  for (int i = 1; i + 1 < argc; i += 2) {
    if (std::strcmp(argv[i], "--mb") == 0) mb = std::atof(argv[i + 1]);
    if (std::strcmp(argv[i], "--dir") == 0) dir = argv[i + 1];
  }
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::size_t n_chunks = static_cast<std::size_t>(mb * 1e6 / kChunkBytes);
  const std::vector<std::uint8_t> data = ambdiag::bench::seeded_samples(n_chunks);
  std::printf("%zu chunks of %zu bytes (%.0f MB), %d channels; files in %s; SQLite %s\n", n_chunks, kChunkBytes,
              static_cast<double>(data.size()) / 1e6, kChannels, dir.c_str(), sqlite3_libversion());

  for (int batch : {100, 1000}) bare_sqlite(dir / "bare.db", data, n_chunks, batch);

  const std::vector<Chunk> chunks = ambdiag::bench::chunks_of(data);
  const std::string db_path = (dir / "historian.db").string();
  std::string last_run;
  for (std::size_t batch : {100u, 1000u}) {
    fs::remove(db_path);
    auto h = Historian::open(db_path);
    last_run = "P-1/batch" + std::to_string(batch);
    h.begin_run(ambdiag::storage::run_header_from_json(run_json(last_run)));
    Timer t;
    for (std::size_t i = 0; i < n_chunks; i += batch)
      h.put_chunks(last_run, std::span(chunks).subspan(i, std::min(batch, n_chunks - i)));
    report(("Historian::put_chunks, " + std::to_string(batch) + " chunks/call").c_str(),
           static_cast<double>(data.size()), t);
  }
  auto h = Historian::open(db_path);
  {
    Timer t;
    const auto end = h.end_run(last_run, static_cast<std::int64_t>(n_chunks) * kFramesPerChunk,
                               ambdiag::fnv1a64(data.data(), data.size()));
    report(end.status == ambdiag::storage::RunStatus::complete ? "Historian::end_run (verify, complete)"
                                                               : "Historian::end_run (INCOMPLETE!)",
           static_cast<double>(data.size()), t);
  }
  {
    auto r = Historian::open(db_path, Historian::Mode::read);
    Timer t;
    std::size_t n = 0;
    r.stream_samples(last_run, [&](std::span<const std::uint8_t> b) {
      n += b.size();
      return true;
    });
    report("Historian::stream_samples (read back)", static_cast<double>(n), t);
    Timer t2;
    const std::string all = r.read_samples(last_run);
    report("Historian::read_samples (into one string)", static_cast<double>(all.size()), t2);
    if (all.size() != data.size() || std::memcmp(all.data(), data.data(), data.size()) != 0) {
      std::fprintf(stderr, "bench_storage: read-back differs!\n");
      return 1;
    }
  }

  ambdiag::server::RestOptions opt;
  opt.db_path = db_path;
  opt.host = "127.0.0.1";
  ambdiag::server::RestServer server(opt);
  const int port = server.start();
  {
    httplib::Client c("127.0.0.1", port);
    c.set_read_timeout(60, 0);
    const std::string url = "/api/v1/runs/" + ambdiag::server::url_encode_segment(last_run) + "/samples.f32";
    Timer t;
    std::size_t n = 0;
    for (int k = 0; k < 3; ++k) {
      const auto r = c.Get(url, [&](const char*, size_t len) {
        n += len;
        return true;
      });
      if (!r || r->status != 200) {
        std::fprintf(stderr, "bench_storage: download failed\n");
        return 1;
      }
    }
    report("REST GET samples.f32 (3 downloads, streamed)", static_cast<double>(n), t);
  }
  for (int clients : {1, 8, 50}) {
    std::atomic<long> ok{0};
    std::atomic<bool> stop{false};
    std::vector<std::thread> threads;
    Timer t;
    for (int i = 0; i < clients; ++i) {
      threads.emplace_back([&] {
        httplib::Client c("127.0.0.1", port);
        c.set_keep_alive(true);
        while (!stop) {
          const auto r = c.Get("/api/v1/health");
          if (r && r->status == 200) ++ok;
        }
      });
    }
    std::this_thread::sleep_for(std::chrono::seconds(2));
    stop = true;
    for (auto& th : threads) th.join();
    std::printf("REST GET /api/v1/health, %2d keep-alive clients      %8.0f requests/s wall %8.0f per CPU-s\n",
                clients, static_cast<double>(ok) / t.wall(), static_cast<double>(ok) / t.cpu());
  }
  server.stop();
  fs::remove_all(dir);
  return 0;
}
