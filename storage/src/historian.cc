#include "ambdiag/storage/historian.h"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cstring>
#include <ctime>
#include <limits>
#include <stdexcept>
#include <string_view>
#include <thread>
#include <unordered_map>

#include <nlohmann/json.hpp>

#include "ambdiag/core/checksum.h"
#include "ambdiag/core/error.h"
#include "background_checkpoint.h"
#include "historian_impl.h"
#include "schema.h"
#include "sql/postgres/pg_db.h"
#include "sql/postgres/pg_schema.h"
#include "sql/sqlite/sqlite_db.h"

namespace ambdiag::storage {

std::string now_utc() { return utc_ms(std::chrono::system_clock::now()); }

std::string utc_ms(std::chrono::system_clock::time_point at) {
  const auto total_ms = std::chrono::duration_cast<std::chrono::milliseconds>(at.time_since_epoch()).count();
  const std::time_t t = static_cast<std::time_t>(total_ms >= 0 ? total_ms / 1000 : -((999 - total_ms) / 1000));
  const auto ms = total_ms - static_cast<std::int64_t>(t) * 1000;  // 0..999, also before 1970
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[96];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday,
                tm.tm_hour, tm.tm_min, tm.tm_sec, static_cast<int>(ms));
  return buf;
}

std::string hex64(std::uint64_t v) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "0x%016llx", static_cast<unsigned long long>(v));
  return buf;
}

RunStatus status_from_text(const std::string& s) {
  if (s == "complete") return RunStatus::complete;
  if (s == "incomplete") return RunStatus::incomplete;
  return RunStatus::receiving;
}

namespace {

// The run columns in the order read_run_row expects (kRunColumns of them).
#define AMBDIAG_RUN_COLUMNS                                                                                  \
  "run_id, pump_id, kind, started_at, speed_rpm, sample_rate_hz, n_channels, status, status_reason, "       \
  "expected_frames, expected_checksum, received_chunks, received_frames, duplicate_chunks, created_at, " \
  "updated_at, ended_at, checksum_kind, samples_dropped_at, samples_dropped_bytes, frf_dropped_at, frf_dropped_bytes"

// Counted from the list, so a column added there moves what follows it
// (find_run's header) with it.
constexpr int kRunColumns = static_cast<int>(std::ranges::count(std::string_view(AMBDIAG_RUN_COLUMNS), ',')) + 1;
static_assert(kRunColumns == 22, "read_run_row reads columns 0..21");

RunInfo read_run_row(const Stmt& s) {
  RunInfo r;
  r.run_id = s.col_text(0);
  r.pump_id = s.col_text(1);
  r.kind = s.col_text(2);
  r.started_at = s.col_text(3);
  r.speed_rpm = s.col_double(4);
  r.sample_rate_hz = s.col_double(5);
  r.n_channels = static_cast<int>(s.col_int(6));
  r.status = status_from_text(s.col_text(7));
  r.status_reason = s.col_text(8);
  r.expected_frames = s.col_opt_int(9);
  if (auto c = s.col_opt_int(10)) r.expected_checksum = std::bit_cast<std::uint64_t>(*c);
  r.received_chunks = s.col_int(11);
  r.received_frames = s.col_int(12);
  r.duplicate_chunks = s.col_int(13);
  r.created_at = s.col_text(14);
  r.updated_at = s.col_text(15);
  r.ended_at = s.col_opt_text(16);
  if (auto k = s.col_opt_text(17)) r.checksum_kind = checksum_kind_from(*k);
  r.samples_dropped_at = s.col_opt_text(18);
  r.samples_dropped_bytes = s.col_int(19);
  r.frf_dropped_at = s.col_opt_text(20);
  r.frf_dropped_bytes = s.col_int(21);
  return r;
}

}  // namespace

bool is_postgres_location(const std::string& location) {
  return location.starts_with("postgresql://") || location.starts_with("postgres://");
}

std::string display_location(const std::string& location) {
  if (!is_postgres_location(location)) return location;
  std::string out = location;
  // postgresql://user:PASSWORD@host/...: the user info ends at the last '@'
  // before the path.
  const size_t start = out.find("://") + 3;
  const size_t end = std::min(out.find('/', start), out.find('?', start));
  const size_t at = out.rfind('@', end == std::string::npos ? std::string::npos : end);
  if (at != std::string::npos && at >= start) {
    const size_t colon = out.find(':', start);
    if (colon != std::string::npos && colon < at) out.replace(colon + 1, at - colon - 1, "***");
  }
  // ...?password=PASSWORD&...
  for (size_t q = out.find('?'); q != std::string::npos; q = out.find('&', q + 1)) {
    if (out.compare(q + 1, 9, "password=") != 0) continue;
    const size_t v = q + 10, e = out.find('&', v);
    out.replace(v, (e == std::string::npos ? out.size() : e) - v, "***");
  }
  return out;
}

Historian Historian::open(const std::string& location, Mode mode) {
  const bool ro = mode == Mode::read;
  if (is_postgres_location(location)) {
    if (detail::pg_latest_schema_version() != detail::latest_schema_version())
      throw std::logic_error("schema version " + std::to_string(detail::latest_schema_version()) +
                             " in SQLite but " + std::to_string(detail::pg_latest_schema_version()) +
                             " in PostgreSQL: a migration must be added to both (docs/storage.md)");
    // Opening takes transactions (the schema, the day partitions): one
    // whose connection is lost (PostgreSQL restarting) is opened again once
    // the location was reached (by this open too), as PgDb::open's reconnect.
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    for (;;) {
      try {
        auto db = detail::PgDb::open(location, ro);
        detail::pg_migrate(*db, ro);
        auto impl = std::make_unique<Impl>(std::move(db), ro);
        impl->ensure_chunk_partitions(std::chrono::system_clock::now());
        return Historian(std::move(impl));
      } catch (const StorageError&) {
        if (!detail::PgDb::reached_before(location) || std::chrono::steady_clock::now() >= until) throw;
        std::this_thread::sleep_for(std::chrono::milliseconds(200));
      }
    }
  }
  auto db = std::make_unique<detail::Db>(
      detail::Db::open(location, ro ? SQLITE_OPEN_READWRITE : SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE));
  detail::set_pragmas(*db, ro);
  detail::migrate(*db, ro);
  return Historian(std::make_unique<Impl>(std::move(db), ro));
}

Historian::Historian(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Historian::Historian(Historian&&) noexcept = default;
Historian& Historian::operator=(Historian&&) noexcept = default;
Historian::~Historian() = default;

int Historian::schema_version() { return detail::latest_schema_version(); }
const std::string& Historian::path() const { return impl_->db.path(); }

void Historian::begin_run(const RunHeader& header) {
  impl_->require_writer("begin_run");
  const std::string ctx = "begin_run " + quoted(header.run_id);
  // The fields must be what the stored run.json text says.
  const RunHeader parsed = run_header_from_json(header.header_json, ctx + ": header_json");
  if (parsed.run_id != header.run_id || parsed.pump_id != header.pump_id || parsed.kind != header.kind ||
      parsed.started_at != header.started_at || parsed.speed_rpm != header.speed_rpm ||
      parsed.sample_rate_hz != header.sample_rate_hz || parsed.channels.size() != header.channels.size())
    throw InputError(ctx + ": the header fields disagree with header_json (build it with run_header_from_json)");

  // PostgreSQL: the day partition its chunks go to exists (once a day).
  impl_->ensure_chunk_partitions(std::chrono::system_clock::now());
  auto& db = impl_->db;
  Transaction tx(db, Transaction::Kind::write);
  impl_->lock(Impl::LockSpace::run, header.run_id);  // the check below stays true until the insert
  {
    auto& s = impl_->stmt("SELECT header FROM runs WHERE run_id = ?");
    s.bind(1, header.run_id);
    if (s.step()) {
      const auto held = nlohmann::json::parse(s.col_text(0));
      s.reset();
      if (held == nlohmann::json::parse(header.header_json)) return;  // the same run again
      throw InputError(ctx + ": another header is already stored under this run_id");
    }
  }
  const std::string now = now_utc();
  impl_->register_pump(header.pump_id, now);
  impl_->stmt(
          "INSERT INTO runs (run_id, pump_id, kind, started_at, speed_rpm, sample_rate_hz, n_channels, header, "
          "status, created_at, updated_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, 'receiving', ?, ?)")
      .bind(1, header.run_id)
      .bind(2, header.pump_id)
      .bind(3, header.kind)
      .bind(4, header.started_at)
      .bind(5, header.speed_rpm)
      .bind(6, header.sample_rate_hz)
      .bind(7, static_cast<std::int64_t>(header.channels.size()))
      .bind(8, header.header_json)
      .bind(9, now)
      .bind(10, now)
      .run();
  auto& ch = impl_->stmt("INSERT INTO channels (run_id, idx, name, role, unit, input) VALUES (?, ?, ?, ?, ?, ?)");
  for (size_t i = 0; i < header.channels.size(); ++i) {
    const auto& c = header.channels[i];
    ch.reset()
        .bind(1, header.run_id)
        .bind(2, static_cast<std::int64_t>(i))
        .bind(3, c.name)
        .bind(4, c.role)
        .bind(5, c.unit)
        .bind(6, c.input)
        .run();
  }
  tx.commit();
}

PutResult Historian::put_chunks(const std::string& run_id, std::span<const Chunk> chunks) {
  impl_->require_writer("put_chunks");
  const std::string ctx = "put_chunks " + quoted(run_id);
  auto& db = impl_->db;
  Transaction tx(db, Transaction::Kind::write);
  const auto st = impl_->run_state(run_id, "put_chunks", true);
  Impl::require_samples(st, run_id, "put_chunks");  // neither restored nor compared: the bytes are gone
  const auto frame_bytes = static_cast<std::int64_t>(st.n_channels) * 4;
  for (const auto& c : chunks) {
    const std::string where = ctx + " chunk seq " + std::to_string(c.seq);
    if (c.seq < 0) throw InputError(where + ": seq must be >= 0");
    if (c.first_frame < 0) throw InputError(where + ": first_frame must be >= 0");
    if (c.n_frames <= 0) throw InputError(where + ": n_frames must be > 0");
    if (c.n_frames > std::numeric_limits<std::int32_t>::max() / frame_bytes ||
        static_cast<std::int64_t>(c.bytes.size()) != c.n_frames * frame_bytes)
      throw InputError(where + ": " + std::to_string(c.bytes.size()) + " bytes, but " + std::to_string(c.n_frames) +
                       " frames of " + std::to_string(st.n_channels) + " float32 channels need " +
                       std::to_string(c.n_frames * frame_bytes));
  }
  PutResult result;
  std::int64_t frames = 0;
  // PostgreSQL's chunks carry their run's created_at, the time they are
  // partitioned by (pg_schema.cc), or the kept partition's time once
  // retention moved the run's chunks there: a re-sent chunk then meets the
  // one held (same key) and is a duplicate. No conflict target: the key is
  // (run_id, seq) in SQLite, (run_id, seq, run_created_at) in PostgreSQL.
  auto& ins = impl_->dialect() == Dialect::postgres
                  ? impl_->stmt(
                        "INSERT INTO sample_chunks (run_id, seq, first_frame, n_frames, data, run_created_at) "
                        "VALUES (?, ?, ?, ?, ?, ?) ON CONFLICT DO NOTHING")
                  : impl_->stmt(
                        "INSERT INTO sample_chunks (run_id, seq, first_frame, n_frames, data) VALUES (?, ?, ?, ?, ?) "
                        "ON CONFLICT (run_id, seq) DO NOTHING");
  for (const auto& c : chunks) {
    ins.bind(1, run_id).bind(2, c.seq).bind(3, c.first_frame).bind(4, c.n_frames).bind_blob(5, c.bytes);
    if (impl_->dialect() == Dialect::postgres) ins.bind(6, st.chunks_at);
    ins.send();
  }
  const auto inserted = ins.sent();
  for (size_t k = 0; k < chunks.size(); ++k) {
    const auto& c = chunks[k];
    if (inserted[k] == 1) {
      if (st.status == RunStatus::complete)
        throw InputError(ctx + " chunk seq " + std::to_string(c.seq) + ": the run is complete; no new chunks");
      ++result.stored;
      frames += c.n_frames;
      continue;
    }
    auto& held = impl_->stmt("SELECT first_frame, n_frames, data FROM sample_chunks WHERE run_id = ? AND seq = ?");
    held.bind(1, run_id).bind(2, c.seq);
    if (!held.step()) throw StorageError(ctx + ": chunk neither inserted nor held");
    const auto blob = held.col_blob(2);
    const bool same = held.col_int(0) == c.first_frame && held.col_int(1) == c.n_frames &&
                      blob.size() == c.bytes.size() && std::memcmp(blob.data(), c.bytes.data(), blob.size()) == 0;
    held.reset();
    if (!same)
      throw InputError(ctx + " chunk seq " + std::to_string(c.seq) +
                       ": already held with other frames or bytes (a duplicate must be identical)");
    ++result.duplicates;
  }
  impl_->stmt(
          "UPDATE runs SET received_chunks = received_chunks + ?, received_frames = received_frames + ?, "
          "duplicate_chunks = duplicate_chunks + ?, updated_at = ? WHERE run_id = ?")
      .bind(1, result.stored)
      .bind(2, frames)
      .bind(3, result.duplicates)
      .bind(4, now_utc())
      .bind(5, run_id)
      .run();
  tx.commit();
  return result;
}

namespace {

// One pass over a run's chunks in seq order: contiguity, frame total and
// (when `with_blobs`) the checksum. Without blobs only the chunk index and
// the rows' first bytes are read: a blob is the row's last column, so its
// overflow pages stay on disk.
struct ChunkScan {
  std::string gap;  // first problem of seq / first_frame, empty if none
  std::int64_t n_chunks = 0, frames = 0;
  std::uint64_t hash = kFnv1a64Init;
};

ChunkScan scan_chunks(Historian::Impl& impl, const std::string& run_id, bool with_blobs, ChecksumKind kind) {
  ChunkScan r;
  r.hash = run_checksum_init(kind);
  std::int64_t next_seq = 0, next_frame = 0;
  auto& s = with_blobs ? impl.stmt("SELECT seq, first_frame, n_frames, data FROM sample_chunks WHERE run_id = ? ORDER BY seq",
                                   Fetch::one_by_one)
                       : impl.stmt("SELECT seq, first_frame, n_frames FROM sample_chunks WHERE run_id = ? ORDER BY seq");
  s.bind(1, run_id);
  while (s.step()) {
    const std::int64_t seq = s.col_int(0), first = s.col_int(1), n = s.col_int(2);
    if (r.gap.empty() && seq != next_seq)
      r.gap = seq - next_seq == 1 ? "missing chunk seq " + std::to_string(next_seq)
                                  : "missing chunks seq " + std::to_string(next_seq) + ".." + std::to_string(seq - 1);
    else if (r.gap.empty() && first != next_frame)
      r.gap = "chunk seq " + std::to_string(seq) + " starts at frame " + std::to_string(first) + ", expected " +
              std::to_string(next_frame);
    if (with_blobs) {
      const auto blob = s.col_blob(3);
      r.hash = block_checksums(kind, blob.data(), blob.size(), r.hash).run_after;
    }
    ++r.n_chunks;
    r.frames += n;
    next_seq = seq + 1;
    next_frame = first + n;
  }
  s.reset();
  return r;
}

}  // namespace

EndResult Historian::end_run(const std::string& run_id, std::int64_t total_frames, std::uint64_t checksum,
                             std::optional<HeldDigest> digest, ChecksumKind kind) {
  impl_->require_writer("end_run");
  const std::string ctx = "end_run " + quoted(run_id);
  if (total_frames < 0) throw InputError(ctx + ": total_frames must be >= 0");
  auto& db = impl_->db;
  Transaction tx(db, Transaction::Kind::write);
  const auto st = impl_->run_state(run_id, "end_run", true);
  if (st.status == RunStatus::complete) {
    if (st.expected_frames == total_frames && st.expected_checksum == checksum)
      return {RunStatus::complete, "", total_frames, checksum, false};  // the same end again
    throw InputError(ctx + ": the run is already complete with " + std::to_string(st.expected_frames.value_or(0)) +
                     " frames and checksum " + hex64(st.expected_checksum.value_or(0)) + "; this end says " +
                     std::to_string(total_frames) + " frames and " + hex64(checksum));
  }
  Impl::require_samples(st, run_id, "end_run");  // nothing left to check
  EndResult r;
  ChunkScan scan;
  if (digest && digest->kind == kind) {
    scan = scan_chunks(*impl_, run_id, false, kind);
    r.used_digest = scan.gap.empty() && scan.n_chunks == digest->n_chunks;  // exactly seq 0..n-1
    scan.hash = digest->checksum;
  }
  if (!r.used_digest) scan = scan_chunks(*impl_, run_id, true, kind);
  r.frames_held = scan.frames;
  r.checksum_held = scan.hash;
  if (!scan.gap.empty()) {
    r.reason = scan.gap;
  } else if (r.frames_held != total_frames) {
    r.reason = (r.frames_held < total_frames ? "missing frames: " : "too many frames: ") + std::to_string(r.frames_held) +
               " held, the run end says " + std::to_string(total_frames);
  } else if (scan.hash != checksum) {
    r.reason = "checksum mismatch: the chunks held hash to " + hex64(scan.hash) + ", the run end says " + hex64(checksum);
  }
  r.status = r.reason.empty() ? RunStatus::complete : RunStatus::incomplete;
  const std::string now = now_utc();
  impl_->stmt(
          "UPDATE runs SET status = ?, status_reason = ?, expected_frames = ?, expected_checksum = ?, ended_at = ?, "
          "updated_at = ?, checksum_kind = ? WHERE run_id = ?")
      .bind(1, to_string(r.status))
      .bind(2, r.reason)
      .bind(3, total_frames)
      .bind(4, std::bit_cast<std::int64_t>(checksum))
      .bind(5, now)
      .bind(6, now)
      .bind(7, std::string(to_string(kind)))
      .bind(8, run_id)
      .run();
  tx.commit();
  return r;
}

RunStatus Historian::mark_incomplete(const std::string& run_id, const std::string& reason) {
  impl_->require_writer("mark_incomplete");
  if (reason.empty()) throw InputError("mark_incomplete " + quoted(run_id) + ": a reason is required");
  Transaction tx(impl_->db, Transaction::Kind::write);
  const auto st = impl_->run_state(run_id, "mark_incomplete", true);
  if (st.status == RunStatus::complete) return RunStatus::complete;
  impl_->stmt("UPDATE runs SET status = 'incomplete', status_reason = ?, updated_at = ? WHERE run_id = ?")
      .bind(1, reason)
      .bind(2, now_utc())
      .bind(3, run_id)
      .run();
  tx.commit();
  return RunStatus::incomplete;
}

namespace {

constexpr const char* kPumpSummarySql =
    "SELECT p.pump_id, (SELECT count(*) FROM runs r WHERE r.pump_id = p.pump_id), "
    "coalesce((SELECT run_id FROM runs r WHERE r.pump_id = p.pump_id ORDER BY started_at DESC, run_id DESC LIMIT 1), ''), "
    "coalesce((SELECT started_at FROM runs r WHERE r.pump_id = p.pump_id ORDER BY started_at DESC, run_id DESC LIMIT 1), '') "
    "FROM pumps p ";

PumpSummary read_pump_row(const Stmt& s) { return {s.col_text(0), s.col_int(1), s.col_text(2), s.col_text(3)}; }

}  // namespace

std::vector<PumpSummary> Historian::list_pumps() {
  static const std::string sql = std::string(kPumpSummarySql) + "ORDER BY p.pump_id";
  auto& s = impl_->stmt(sql.c_str());
  std::vector<PumpSummary> out;
  while (s.step()) out.push_back(read_pump_row(s));
  return out;
}

std::optional<PumpSummary> Historian::find_pump(const std::string& pump_id) {
  static const std::string sql = std::string(kPumpSummarySql) + "WHERE p.pump_id = ?";
  auto& s = impl_->stmt(sql.c_str());
  s.bind(1, pump_id);
  if (!s.step()) return std::nullopt;
  auto p = read_pump_row(s);
  s.reset();
  return p;
}

std::vector<RunInfo> Historian::list_runs(const std::string& pump_id) {
  auto& s = impl_->stmt("SELECT " AMBDIAG_RUN_COLUMNS " FROM runs WHERE pump_id = ? ORDER BY started_at, run_id");
  s.bind(1, pump_id);
  std::vector<RunInfo> out;
  while (s.step()) out.push_back(read_run_row(s));
  return out;
}

std::optional<RunInfo> Historian::find_run(const std::string& run_id) {
  auto& s = impl_->stmt("SELECT " AMBDIAG_RUN_COLUMNS ", header FROM runs WHERE run_id = ?");
  s.bind(1, run_id);
  if (!s.step()) return std::nullopt;
  RunInfo r = read_run_row(s);
  r.header_json = s.col_text(kRunColumns);
  s.reset();
  return r;
}

std::int64_t Historian::count_runs() {
  auto& s = impl_->stmt("SELECT count(*) FROM runs");
  s.step();
  const auto n = s.col_int(0);
  s.reset();
  return n;
}

std::string Historian::read_samples(const std::string& run_id) {
  std::string out;
  auto snap = snapshot();
  if (auto r = find_run(run_id)) out.reserve(static_cast<size_t>(r->samples_bytes()));
  stream_samples(run_id, [&](std::span<const std::uint8_t> b) {
    out.append(reinterpret_cast<const char*>(b.data()), b.size());
    return true;
  });
  return out;
}

bool Historian::stream_samples(const std::string& run_id,
                               const std::function<bool(std::span<const std::uint8_t>)>& sink) {
  Transaction tx(impl_->db, Transaction::Kind::read);
  Impl::require_samples(impl_->run_state(run_id, "samples"), run_id, "run");
  auto& s = impl_->stmt("SELECT data FROM sample_chunks WHERE run_id = ? ORDER BY seq", Fetch::one_by_one);
  s.bind(1, run_id);
  while (s.step()) {
    if (!sink(s.col_blob(0))) {
      s.reset();
      return false;
    }
  }
  tx.commit();
  return true;
}

Historian::WriteBatch::WriteBatch(Historian* h) : h_(h) {
  auto& impl = *h_->impl_;
  impl.require_writer("write_batch");
  if (impl.db.in_transaction()) throw std::logic_error("Historian::write_batch inside another transaction");
  impl.batch_tx.emplace(impl.db, Transaction::Kind::write);
}

Historian::WriteBatch::~WriteBatch() {
  if (!h_) return;
  h_->impl_->batch_events.clear();
  h_->impl_->batch_tx.reset();  // rolls back unless committed
}

void Historian::WriteBatch::commit() {
  if (!h_) return;
  auto& impl = *h_->impl_;
  h_ = nullptr;
  struct Reset {  // the batch is over whether COMMIT succeeds or not
    Impl& i;
    ~Reset() {
      i.batch_events.clear();
      i.batch_tx.reset();
    }
  } reset{impl};
  // The batch's events last: the events' lock is the last one it takes.
  if (!impl.batch_events.empty()) write_events(impl, impl.batch_events);
  impl.batch_tx->commit();
}

Historian::WriteBatch Historian::write_batch() { return WriteBatch(this); }

void Historian::checkpoint_in_background(int trigger_pages) {
  checkpoint_in_background(CheckpointOptions{.trigger_pages = trigger_pages, .inline_pages = 16 * trigger_pages});
}

void Historian::checkpoint_in_background(const CheckpointOptions& opt) {
  impl_->require_writer("checkpoint_in_background");
  if (impl_->checkpointer) throw std::logic_error("Historian::checkpoint_in_background called twice");
  if (opt.trigger_pages < 1 || opt.inline_pages < opt.trigger_pages)
    throw std::invalid_argument("Historian::checkpoint_in_background: need 1 <= trigger_pages <= inline_pages");
  if (opt.durable_within.count() <= 0)
    throw std::invalid_argument("Historian::checkpoint_in_background: durable_within must be > 0");
  if (impl_->dialect() == Dialect::postgres)  // durable at commit; checkpoints are the server's
    impl_->checkpointer = std::make_unique<detail::DurableAtCommit>(impl_->db);
  else
    impl_->checkpointer = std::make_unique<detail::BackgroundCheckpoint>(static_cast<detail::Db&>(impl_->db).get(),
                                                                         impl_->db.path(), opt);
}

namespace {
detail::Durability& tracker(const std::unique_ptr<detail::Durability>& c, const char* what) {
  if (!c) throw std::logic_error(std::string("Historian::") + what + " needs checkpoint_in_background");
  return *c;
}
}  // namespace

std::uint64_t Historian::commit_generation() const {
  return tracker(impl_->checkpointer, "commit_generation").commit_generation();
}

std::uint64_t Historian::durable_generation() const {
  return tracker(impl_->checkpointer, "durable_generation").durable_generation();
}

void Historian::on_durable(std::function<void(std::uint64_t)> listener) {
  tracker(impl_->checkpointer, "on_durable").on_durable(std::move(listener));
}

CheckpointStats Historian::checkpoint_stats() const {
  return impl_->checkpointer ? impl_->checkpointer->stats() : CheckpointStats{};
}

Historian::Snapshot::Snapshot(Historian* h) : h_(h) {
  auto& impl = *h_->impl_;
  if (impl.snapshot_depth++ == 0 && !impl.db.in_transaction())
    impl.snapshot_tx.emplace(impl.db, Transaction::Kind::read);
}

Historian::Snapshot::Snapshot(Snapshot&& o) noexcept : h_(o.h_) { o.h_ = nullptr; }

Historian::Snapshot::~Snapshot() {
  if (!h_) return;
  auto& impl = *h_->impl_;
  if (--impl.snapshot_depth == 0) impl.snapshot_tx.reset();  // ends the read transaction
}

Historian::Snapshot Historian::snapshot() { return Snapshot(this); }

}  // namespace ambdiag::storage
