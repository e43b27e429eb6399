// bench_pg_ingest: sample ingest into PostgreSQL against SQLite
// (docs/benchmarks.md, "Ingest into PostgreSQL (issue 22)").
//
//   bench_pg_ingest --pg URI [--mb N] [--dir DIR]
//
// URI: a PostgreSQL database the bench may create the schemas
// ambdiag_bench_raw and ambdiag_bench_h in (dropped at the start and end).
// First the ways libpq can move 32 KiB chunks into a table with duplicate
// detection (one prepared INSERT per chunk, the same pipelined, COPY into
// a staging table then INSERT ... ON CONFLICT, and bare COPY as the
// ceiling); then Historian::put_chunks, end_run and the read-back on
// PostgreSQL and on an SQLite file, with the same chunks.
//
// Figures: wall time; CPU of this process; and on PostgreSQL the CPU of the
// server process of the connection (/proc/PID/stat of pg_backend_pid(): a
// server on this machine, readable by this user), which does most of the work.
#include <libpq-fe.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "ambdiag/core/checksum.h"
#include "ambdiag/storage/historian.h"
#include "bench_chunks.h"
#include "bench_pg.h"
#include "bench_util.h"

namespace {

namespace fs = std::filesystem;
using ambdiag::storage::Chunk;
using ambdiag::storage::Historian;

using ambdiag::bench::kChunkBytes;
using ambdiag::bench::kFramesPerChunk;
using ambdiag::bench::run_json;

[[noreturn]] void die(const std::string& what) { ambdiag::bench::pg_die("bench_pg_ingest", what); }

struct Conn : ambdiag::bench::PgConn {
  explicit Conn(const std::string& uri) : PgConn("bench_pg_ingest", uri) {}
};

// CPU seconds of a process on this machine (utime + stime of /proc/PID/stat).
double process_cpu_seconds(long pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  std::getline(in, line);
  const auto close = line.rfind(')');
  if (close == std::string::npos) return 0.0;
  std::istringstream rest(line.substr(close + 2));
  std::string field;
  double ticks = 0.0;
  for (int k = 3; rest >> field; ++k)
    if (k == 14 || k == 15) ticks += std::atof(field.c_str());
  return ticks / static_cast<double>(sysconf(_SC_CLK_TCK));
}

struct Timer {
  long server_pid = 0;  // a PostgreSQL backend, 0 for none
  double w0 = ambdiag::bench::wall_seconds(), c0 = ambdiag::bench::cpu_seconds();
  double s0 = server_pid ? process_cpu_seconds(server_pid) : 0.0;
  explicit Timer(long pid = 0) : server_pid(pid), s0(pid ? process_cpu_seconds(pid) : 0.0) {}
  void report(const std::string& what, double bytes) const {
    const double w = ambdiag::bench::wall_seconds() - w0, c = ambdiag::bench::cpu_seconds() - c0;
    std::printf("%-58s %7.1f MB/s wall  (%.2f s wall, %.2f s CPU here", what.c_str(), bytes / w / 1e6, w, c);
    if (server_pid) std::printf(", %.2f s CPU in the server", process_cpu_seconds(server_pid) - s0);
    std::printf(")\n");
  }
};

long backend_pid(const Conn& c) { return std::atol(c.exec("SELECT pg_backend_pid()").c_str()); }

std::string be64(std::int64_t v) {
  std::string s(8, '\0');
  for (int k = 0; k < 8; ++k) s[static_cast<size_t>(k)] = static_cast<char>((static_cast<std::uint64_t>(v) >> (56 - 8 * k)) & 0xff);
  return s;
}

std::string be32(std::int32_t v) {
  std::string s(4, '\0');
  for (int k = 0; k < 4; ++k) s[static_cast<size_t>(k)] = static_cast<char>((static_cast<std::uint32_t>(v) >> (24 - 8 * k)) & 0xff);
  return s;
}

enum class Way { insert_each, insert_pipelined, copy_staged, copy_bare };

const char* name_of(Way w) {
  switch (w) {
    case Way::insert_each: return "prepared INSERT ... ON CONFLICT, one round trip each";
    case Way::insert_pipelined: return "prepared INSERT ... ON CONFLICT, pipelined";
    case Way::copy_staged: return "COPY BINARY to staging, INSERT ... ON CONFLICT";
    case Way::copy_bare: return "COPY BINARY into the table (no duplicate check)";
  }
  return "?";
}

// The chunks [first, first + n) into raw.c by `way`, in the open transaction.
void put_raw(const Conn& db, Way way, const std::vector<std::uint8_t>& data, std::size_t first, std::size_t n) {
  const char* ins = "INSERT INTO c (run_id, seq, data) VALUES ($1, $2, $3) ON CONFLICT DO NOTHING";
  const Oid types[3] = {25, 20, 17};
  const int formats[3] = {1, 1, 1};
  if (way == Way::insert_each || way == Way::insert_pipelined) {
    if (way == Way::insert_pipelined && !PQenterPipelineMode(db.c)) die("pipeline mode");
    std::vector<std::string> seqs(n);
    for (std::size_t i = 0; i < n; ++i) {
      seqs[i] = be64(static_cast<std::int64_t>(first + i));
      const char* values[3] = {"P-1/run", seqs[i].data(), reinterpret_cast<const char*>(data.data() + (first + i) * kChunkBytes)};
      const int lengths[3] = {7, 8, static_cast<int>(kChunkBytes)};
      if (way == Way::insert_each) {
        PGresult* r = PQexecParams(db.c, ins, 3, types, values, lengths, formats, 1);
        if (PQresultStatus(r) != PGRES_COMMAND_OK) die(std::string("insert: ") + PQresultErrorMessage(r));
        PQclear(r);
      } else if (!PQsendQueryParams(db.c, ins, 3, types, values, lengths, formats, 1)) {
        die(std::string("send: ") + PQerrorMessage(db.c));
      }
    }
    if (way == Way::insert_each) return;
    PQpipelineSync(db.c);
    for (std::size_t done = 0; done < n;) {  // each query: its result, then nullptr
      PGresult* r = PQgetResult(db.c);
      if (!r) {
        ++done;
        continue;
      }
      if (PQresultStatus(r) != PGRES_COMMAND_OK) die(std::string("pipelined insert: ") + PQresultErrorMessage(r));
      PQclear(r);
    }
    PGresult* sync = PQgetResult(db.c);  // PGRES_PIPELINE_SYNC
    PQclear(sync);
    PQexitPipelineMode(db.c);
    return;
  }
  const std::string target = way == Way::copy_bare ? "c" : "stage";
  if (way == Way::copy_staged) db.exec("TRUNCATE stage");
  PGresult* r = PQexec(db.c, ("COPY " + target + " (run_id, seq, data) FROM STDIN (FORMAT binary)").c_str());
  if (PQresultStatus(r) != PGRES_COPY_IN) die(std::string("copy: ") + PQresultErrorMessage(r));
  PQclear(r);
  std::string buf("PGCOPY\n\377\r\n\0", 11);
  buf += be32(0) + be32(0);
  for (std::size_t i = 0; i < n; ++i) {
    buf += std::string("\0\3", 2) + be32(7) + "P-1/run" + be32(8) + be64(static_cast<std::int64_t>(first + i)) +
           be32(static_cast<std::int32_t>(kChunkBytes));
    buf.append(reinterpret_cast<const char*>(data.data() + (first + i) * kChunkBytes), kChunkBytes);
    if (buf.size() > (1 << 20)) {
      if (PQputCopyData(db.c, buf.data(), static_cast<int>(buf.size())) != 1) die("copy data");
      buf.clear();
    }
  }
  buf += std::string("\377\377", 2);
  if (PQputCopyData(db.c, buf.data(), static_cast<int>(buf.size())) != 1 || PQputCopyEnd(db.c, nullptr) != 1)
    die("copy end");
  r = PQgetResult(db.c);
  if (PQresultStatus(r) != PGRES_COMMAND_OK) die(std::string("copy: ") + PQresultErrorMessage(r));
  PQclear(r);
  while ((r = PQgetResult(db.c))) PQclear(r);
  if (way == Way::copy_staged)
    db.exec("INSERT INTO c (run_id, seq, data) SELECT run_id, seq, data FROM stage ON CONFLICT DO NOTHING");
}

void bare(const std::string& uri, const std::vector<std::uint8_t>& data, std::size_t n_chunks) {
  Conn db(uri);
  const long pid = backend_pid(db);
  for (const Way way : {Way::insert_each, Way::insert_pipelined, Way::copy_staged, Way::copy_bare})
    for (std::size_t batch : {100u, 1000u}) {
      db.exec("DROP SCHEMA IF EXISTS ambdiag_bench_raw CASCADE; CREATE SCHEMA ambdiag_bench_raw; SET search_path = ambdiag_bench_raw;"
              "CREATE TABLE c (run_id text NOT NULL, seq bigint NOT NULL, data bytea NOT NULL, PRIMARY KEY (run_id, seq));"
              "ALTER TABLE c ALTER COLUMN data SET STORAGE EXTERNAL;"
              "CREATE TEMP TABLE IF NOT EXISTS stage (run_id text, seq bigint, data bytea)");
      db.exec("CHECKPOINT");  // the last variant's dirty pages are not this one's cost
      Timer t(pid);
      for (std::size_t i = 0; i < n_chunks; i += batch) {
        db.exec("BEGIN");
        put_raw(db, way, data, i, std::min(batch, n_chunks - i));
        db.exec("COMMIT");
      }
      t.report(std::string(name_of(way)) + ", " + std::to_string(batch) + "/tx", static_cast<double>(n_chunks * kChunkBytes));
      if (db.exec("SELECT count(*) FROM c") != std::to_string(n_chunks)) die("rows lost");
    }
  db.exec("DROP SCHEMA ambdiag_bench_raw CASCADE");
}

// put_chunks, end_run and the read-back on one backend. `admin`: on
// PostgreSQL, a connection that finds the historian's server process by its
// application_name (nullptr: SQLite).
void historian(const std::string& label, const std::string& location, const std::vector<std::uint8_t>& data,
               std::size_t n_chunks, const Conn* admin) {
  const std::vector<Chunk> chunks = ambdiag::bench::chunks_of(data);
  auto h = Historian::open(location);
  const long pid = admin ? std::atol(admin->exec("SELECT pid FROM pg_stat_activity WHERE application_name = "
                                                 "'bench_pg_ingest' ORDER BY backend_start DESC LIMIT 1")
                                         .c_str())
                         : 0;
  std::string last_run;
  for (std::size_t batch : {100u, 1000u}) {
    last_run = "P-1/batch" + std::to_string(batch);
    h.begin_run(ambdiag::storage::run_header_from_json(run_json(last_run)));
    Timer t(pid);
    for (std::size_t i = 0; i < n_chunks; i += batch)
      h.put_chunks(last_run, std::span(chunks).subspan(i, std::min(batch, n_chunks - i)));
    t.report(label + ": Historian::put_chunks, " + std::to_string(batch) + " chunks/call", static_cast<double>(data.size()));
  }
  {
    Timer t(pid);
    const auto end = h.end_run(last_run, static_cast<std::int64_t>(n_chunks) * kFramesPerChunk,
                               ambdiag::fnv1a64(data.data(), data.size()));
    if (end.status != ambdiag::storage::RunStatus::complete) die("end_run: " + end.reason);
    t.report(label + ": Historian::end_run (reads the run once)", static_cast<double>(data.size()));
  }
  {
    Timer t(pid);
    std::size_t n = 0;
    h.stream_samples(last_run, [&](std::span<const std::uint8_t> b) {
      n += b.size();
      return true;
    });
    t.report(label + ": Historian::stream_samples", static_cast<double>(n));
  }
}

}  // namespace

int main(int argc, char** argv) {
  double mb = 128;
  std::string uri;
  fs::path dir = fs::temp_directory_path() / "ambdiag-bench-pg";
  for (int i = 1; i + 1 < argc; i += 2) {
    if (std::strcmp(argv[i], "--mb") == 0) mb = std::atof(argv[i + 1]);
    if (std::strcmp(argv[i], "--pg") == 0) uri = argv[i + 1];
    if (std::strcmp(argv[i], "--dir") == 0) dir = argv[i + 1];
  }
  if (!ambdiag::storage::is_postgres_location(uri)) die("usage: bench_pg_ingest --pg postgresql://... [--mb N] [--dir DIR]");
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::size_t n_chunks = static_cast<std::size_t>(mb * 1e6 / kChunkBytes);
  const std::vector<std::uint8_t> data = ambdiag::bench::seeded_samples(n_chunks);
  Conn admin(uri);
  std::printf("%zu chunks of %zu bytes (%.0f MB); PostgreSQL %s (fsync %s, synchronous_commit %s); SQLite file in %s\n",
              n_chunks, kChunkBytes, static_cast<double>(data.size()) / 1e6, admin.exec("SHOW server_version").c_str(),
              admin.exec("SHOW fsync").c_str(), admin.exec("SHOW synchronous_commit").c_str(), dir.c_str());
  bare(uri, data, n_chunks);

  admin.exec("DROP SCHEMA IF EXISTS ambdiag_bench_h CASCADE; CREATE SCHEMA ambdiag_bench_h");
  admin.exec("CHECKPOINT");
  const std::string location = ambdiag::bench::pg_schema_location(uri, "ambdiag_bench_h", "bench_pg_ingest");
  {
    auto h = Historian::open(location);  // creates the schema before the clock starts
  }
  historian("PostgreSQL", location, data, n_chunks, &admin);
  historian("SQLite", (dir / "historian.db").string(), data, n_chunks, nullptr);
  admin.exec("DROP SCHEMA ambdiag_bench_h CASCADE");
  fs::remove_all(dir);
  return 0;
}
