// The historian: every run a pump streamed (or a recording imported), kept in
// one SQLite file or in a PostgreSQL database (docs/storage.md has the
// schema, pragmas and migrations, and "PostgreSQL" what differs there).
//
// A run is its header (the recording's run.json, stored verbatim) plus sample
// chunks: chunk `seq` (0, 1, 2, ...) holds `n_frames` frames starting at frame
// `first_frame`, as float32 little-endian interleaved by channel, i.e. a slice
// of the recording's samples.f32. Chunks may arrive in any order and more than
// once; the run end gives the frame count and the FNV-1a 64 checksum of the
// whole samples.f32 (core/checksum.h), and the historian checks both against
// what it holds: the run is then `complete`, or `incomplete` with a reason.
//
// Threads: a Historian is one database connection; use it from one thread at
// a time. SQLite: one writer (Mode::write) per file; readers (Mode::read) open
// their own connection each, in any thread or process. WAL lets readers run
// beside the writer: a reader sees the last committed state and never blocks
// the writer. PostgreSQL: any number of writers and readers, in any number
// of processes; each write call takes the locks its checks need.
//
// Errors: bad input (unknown run, wrong chunk size, conflicting header or
// chunk, a file or database that is not an ambdiag historian or is newer
// than this program, a PostgreSQL server that cannot be reached or refuses
// the login) throws ambdiag::InputError naming what is wrong; nothing of a
// refused call is stored. Disk and database failures throw StorageError.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "ambdiag/core/checksum.h"
#include "ambdiag/storage/alarms.h"
#include "ambdiag/storage/events.h"
#include "ambdiag/storage/ingest_lease.h"
#include "ambdiag/storage/monitoring.h"
#include "ambdiag/storage/retention.h"
#include "ambdiag/storage/service.h"
#include "ambdiag/storage/trends.h"

namespace ambdiag::storage {

// The database failed (I/O error, disk full, locked past the busy timeout).
class StorageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// PostgreSQL broke a deadlock (SQLSTATE 40P01) or a serialization conflict
// (40001) by failing this transaction: nothing of it is kept (a WriteBatch
// must be rolled back whole, not only the call's savepoint) and the same
// transaction may simply be run again (retry_transient). Never on SQLite,
// whose one writer cannot deadlock.
class TransientError : public StorageError {
 public:
  using StorageError::StorageError;
};

// Runs `tx` (one whole write transaction, e.g. a WriteBatch from creation
// to commit) and runs it again after a TransientError, at most `attempts`
// times in all, with a short growing pause (a deadlock's other party
// commits meanwhile). Returns what `tx` returns; the last TransientError and
// any other exception go to the caller. `tx` must start from the same state
// each time: whatever it noted in memory during a rolled-back attempt is
// to be forgotten (docs/storage.md "Lock order").
template <class F>
auto retry_transient(F&& tx, int attempts = 5) {
  for (int attempt = 1;; ++attempt) {
    try {
      return tx();
    } catch (const TransientError&) {
      if (attempt >= attempts) throw;
      std::this_thread::sleep_for(std::chrono::milliseconds(10 * attempt));
    }
  }
}

enum class RunStatus { receiving, complete, incomplete };
std::string to_string(RunStatus s);

// What begin_run needs. Build it with run_header_from_json, which parses and
// checks the run.json text with core's run_from_json.
struct RunHeader {
  std::string run_id;
  std::string pump_id;
  std::string kind;        // identification | monitoring
  std::string started_at;  // ISO 8601
  double speed_rpm = 0.0;
  double sample_rate_hz = 0.0;
  struct Channel {
    std::string name, role, unit, input;
  };
  std::vector<Channel> channels;
  std::string header_json;  // the run.json text, kept byte for byte
};
// Throws InputError (prefixed with `source`) if the text is not a valid run.json.
RunHeader run_header_from_json(const std::string& run_json_text, const std::string& source = "run header");

// One slice of samples.f32; `bytes` must hold n_frames * n_channels * 4 bytes.
struct Chunk {
  std::int64_t seq = 0;
  std::int64_t first_frame = 0;
  std::int64_t n_frames = 0;
  std::span<const std::uint8_t> bytes;
};

struct PutResult {
  std::int64_t stored = 0;      // new chunks
  std::int64_t duplicates = 0;  // chunks already held with the same bytes (ignored)
};

struct RunInfo {
  std::string run_id, pump_id, kind, started_at;
  double speed_rpm = 0.0;
  double sample_rate_hz = 0.0;
  int n_channels = 0;
  RunStatus status = RunStatus::receiving;
  std::string status_reason;  // why incomplete; empty otherwise
  std::optional<std::int64_t> expected_frames;     // from the run end
  std::optional<std::uint64_t> expected_checksum;  // from the run end
  std::optional<ChecksumKind> checksum_kind;       // of expected_checksum (none: ended before schema v3)
  std::int64_t received_chunks = 0;
  std::int64_t received_frames = 0;
  std::int64_t duplicate_chunks = 0;
  std::string created_at, updated_at;  // server clock, ISO 8601 UTC
  std::optional<std::string> ended_at;
  std::string header_json;  // run.json text (find_run only; empty in lists)
  // Retention (retention.h). Set: the samples are gone (a drop a crashed
  // sweep began counts as gone: the next sweep finishes it), with the bytes
  // the sweep deleted; the analyses' files likewise.
  std::optional<std::string> samples_dropped_at, frf_dropped_at;
  std::int64_t samples_dropped_bytes = 0, frf_dropped_bytes = 0;

  // What the run received (a dropped run keeps its figure).
  std::int64_t samples_bytes() const { return received_frames * n_channels * 4; }
};

struct PumpSummary {
  std::string pump_id;
  std::int64_t n_runs = 0;
  std::string last_run_id;
  std::string last_started_at;
};

struct EndResult {
  RunStatus status = RunStatus::receiving;
  std::string reason;  // empty when complete
  std::int64_t frames_held = 0;
  std::uint64_t checksum_held = 0;  // run checksum (of the end's kind) of the chunks held, in seq order
  bool used_digest = false;         // checksum_held came from the caller's HeldDigest
};

// What a writer knows of chunks it put itself: the run checksum of `kind`
// (core/checksum.h) of chunks 0..n_chunks-1 in seq order, computed over the exact bytes it passed to
// put_chunks calls that succeeded (stored, or identical duplicates). With it
// end_run need not read the blobs back (a run of 1 GB costs seconds to
// re-read); it is used only if the run holds exactly chunks 0..n_chunks-1.
struct HeldDigest {
  std::int64_t n_chunks = 0;
  std::uint64_t checksum = kFnv1a64Init;
  ChecksumKind kind = ChecksumKind::fnv1a64;
};

// What the background checkpoints did (Historian::checkpoint_in_background).
struct CheckpointStats {
  std::int64_t background = 0;        // checkpoints by the checkpoint thread
  std::int64_t inline_by_writer = 0;  // by the writer, because the thread fell behind
  std::int64_t pages_copied = 0;      // log pages copied into the database file
  std::int64_t log_pages_last = 0;    // pages in the log at the last checkpoint
  std::int64_t time_triggered = 0;   // started because a commit waited durable_within to be durable
  std::int64_t errors = 0;
  std::string last_error;
  std::uint64_t commit_generation = 0, durable_generation = 0;  // Historian::commit_generation(), durable_generation()
};

// How the background checkpoints run (Historian::checkpoint_in_background).
struct CheckpointOptions {
  int trigger_pages = 1000;   // log pages after a commit that start a checkpoint in the thread
  int inline_pages = 16000;   // the thread fell behind: the writer checkpoints itself
  // A commit not yet durable after this long starts a checkpoint (the time
  // trigger), so a slow stream's acks do not wait for the size trigger.
  std::chrono::milliseconds durable_within{1000};
  // synchronous = FULL on the writer: each commit fsyncs the log and is
  // durable when it returns (docs/storage.md, "Durability", has the cost).
  bool sync_commits = false;
};

// True for a PostgreSQL location: a libpq connection URI, postgresql://...
// or postgres://... (Historian::open); anything else is an SQLite file path.
bool is_postgres_location(const std::string& location);
// The location for messages and logs: a URI's password (user:PASSWORD@ or
// password=PASSWORD) replaced by ***; a file path as it is.
std::string display_location(const std::string& location);

class Historian {
 public:
  enum class Mode {
    write,  // creates the file (or the schema in the database) if missing and migrates it
    read    // the file or schema must exist at the current version; writes refused
  };
  // `location`: an SQLite file path, or a PostgreSQL connection URI
  // (is_postgres_location), whose tables go in the first schema of its
  // search_path (public unless options=-csearch_path%3D... says otherwise).
  // Throws InputError if the file is not an SQLite database, the server
  // cannot be reached or refuses the login, or the file or database is not
  // an ambdiag historian or has a newer schema than this program knows;
  // messages name the location (display_location).
  static Historian open(const std::string& location, Mode mode = Mode::write);

  Historian(Historian&&) noexcept;
  Historian& operator=(Historian&&) noexcept;
  ~Historian();

  static int schema_version();  // the version this program writes
  const std::string& path() const;  // the location given to open()

  // --- writing (Mode::write) ---
  // Registers the pump if new and the run as `receiving`. Idempotent: the
  // same header again is a no-op; another header under the same run_id throws.
  void begin_run(const RunHeader& header);
  // Stores chunks in one transaction (all or nothing). A (run_id, seq) held
  // with the same bytes and frames is a duplicate: counted and ignored; with
  // other bytes it throws. Throws for an unknown run, a size that is not
  // n_frames * n_channels * 4, negative seq/frames, or a new chunk for a
  // complete run or a run whose samples retention dropped.
  PutResult put_chunks(const std::string& run_id, std::span<const Chunk> chunks);
  // The run end: checks seq 0..n-1 without gaps, first_frame contiguous,
  // the frame total and the checksum, reading the run once from the
  // database. Sets `complete` or `incomplete` with the first problem found.
  // Calling it again (e.g. after late chunks of an incomplete run) checks
  // again; on a complete run with the same figures it is a no-op, with other
  // figures it throws. With a `digest` of the same kind that covers every
  // chunk held, the checksum is the digest's and only the chunk index is
  // read. `kind`: how `checksum` is computed (core/checksum.h; a chunk is a
  // block): FNV-1a 64 of the whole run (protocol 1.0 agents, imports) or
  // the chain of the chunks' XXH64 (protocol 1.1 agents).
  EndResult end_run(const std::string& run_id, std::int64_t total_frames, std::uint64_t checksum,
                    std::optional<HeldDigest> digest = std::nullopt, ChecksumKind kind = ChecksumKind::fnv1a64);
  // For a run whose end will not come (agent gone): `incomplete` with the
  // reason. A complete run stays complete. Returns the status afterwards.
  RunStatus mark_incomplete(const std::string& run_id, const std::string& reason);
  // Snapshots in one transaction, each checked with validate() first
  // (InputError naming the field; nothing stored then). Registers unknown
  // pumps. A (pump_id, time_ns) already held is a duplicate: counted, ignored.
  PutResult put_monitoring(std::span<const MonitoringSnapshot> snapshots);

  // Groups the write calls made while it lives into one transaction: one
  // commit for many calls (the server's ingest commits everything it
  // received in one go). Each call inside stays all or nothing on its own (a
  // savepoint), so a refused call does not undo the others. Destroyed
  // without commit(): all of it rolls back. One at a time per Historian.
  class WriteBatch {
   public:
    WriteBatch(WriteBatch&& o) noexcept : h_(o.h_) { o.h_ = nullptr; }
    WriteBatch& operator=(WriteBatch&&) = delete;
    ~WriteBatch();
    void commit();  // throws StorageError; the batch is then rolled back

   private:
    friend class Historian;
    explicit WriteBatch(Historian* h);
    Historian* h_;
  };
  WriteBatch write_batch();

  // Moves the checkpoints (copying the write-ahead log into the database
  // file, with its fsyncs) from the committing writer to a thread and
  // connection of their own: commits no longer wait for them. Started after
  // every `trigger_pages` of log; if the thread falls behind, the writer
  // checkpoints itself at 16 x that, so the log stays bounded. Stops with
  // the Historian. Call once, on a Mode::write historian. PostgreSQL: the
  // server checkpoints itself and a commit is durable when it returns
  // (synchronous_commit on); this only starts the commit numbers below,
  // each commit durable at once (the options are not used).
  void checkpoint_in_background(int trigger_pages = 1000);
  void checkpoint_in_background(const CheckpointOptions& opt);
  CheckpointStats checkpoint_stats() const;  // zeros when not started

  // Durability of this writer's commits (needs checkpoint_in_background):
  // every commit on this connection gets the next number, 1 being the state
  // found at start (a process crash may have left committed but unsynced
  // transactions in the log). durable_generation() is the highest number
  // whose commit, with every one before it, is on disk for good: a power
  // cut keeps it (docs/storage.md, "Durability"). The listener is called
  // with each new durable number, from the checkpoint thread or the writer's
  // (after its commit); it must be quick and must not throw.
  std::uint64_t commit_generation() const;
  std::uint64_t durable_generation() const;
  void on_durable(std::function<void(std::uint64_t durable_generation)> listener);

  // --- pumps: models and references (service.h; historian_registry.cc) ---
  // A new model version of the pump (registered if new): 1 for the first.
  // The text is stored as given; the caller has checked that it parses.
  int put_model(const std::string& pump_id, const std::string& plant_json, const std::string& created_by,
                const std::string& comment = "");
  // That version, or the newest when `version` is empty; nullopt if none.
  std::optional<ModelVersion> find_model(const std::string& pump_id, std::optional<int> version = std::nullopt);
  // Every version, oldest first, without plant_json.
  std::vector<ModelVersion> list_models(const std::string& pump_id);
  // A new reference version of the pump. Throws InputError naming the run
  // when a run is unknown, of another pump, not `complete`, not of kind
  // `identification`, or listed twice, or when the list is empty, and for a
  // run whose samples retention dropped when no analysis of it kept its
  // frf.csv (the reference is learnt from the runs' FRFs).
  int put_reference(const std::string& pump_id, const std::vector<std::string>& run_ids,
                    const std::string& created_by);
  std::optional<ReferenceVersion> find_reference(const std::string& pump_id,
                                                 std::optional<int> version = std::nullopt);

  // --- jobs (service.h; historian_jobs.cc) ---
  // A job with this key, queued, unless one exists already (any status):
  // returns its id and whether it was created now.
  std::pair<std::int64_t, bool> enqueue_job(const JobKey& key, const std::string& params_json = "{}",
                                            std::optional<std::int64_t> depends_on = std::nullopt);
  // The oldest queued job whose dependency is done (a job depending on a
  // failed or cancelled job fails with that reason instead), now running
  // under `worker` with attempts + 1 and a lease until now + `lease`.
  // kinds: only these kinds (empty: any).
  //
  // An attempt **holds** its job while the job is `running` with that
  // attempt number and its lease has not expired (lease_expires_at > now at
  // the time of the write). Every write of an attempt (progress, renewal,
  // finish, fail) is fenced by that; once its lease has expired, the attempt
  // never holds the job again, even before anyone requeued or claimed it.
  std::optional<Job> claim_job(const std::string& worker, const std::vector<std::string>& kinds = {},
                               std::chrono::milliseconds lease = kDefaultJobLease);
  // The holding attempt's lease, now until now + `lease`; false (nothing
  // changed) when the attempt no longer holds the job.
  bool renew_job_lease(std::int64_t job_id, int attempt, std::chrono::milliseconds lease = kDefaultJobLease);
  // Progress of the holding attempt; false (nothing changed) when the
  // attempt no longer holds the job.
  bool set_job_progress(std::int64_t job_id, int attempt, double progress);
  // The attempt's result and files, stored in one transaction with the
  // status `done`. False, storing nothing, when that attempt no longer
  // holds the job (lease expired, requeued, cancelled, another attempt): a
  // result is stored once. `series`: the values the result gives the pump's trend
  // series (analysis jobs of a run only; ignored for other kinds), kept in
  // the same transaction and replacing the run's points of any older
  // analysis job (trends.h). Throws InputError naming a series with an
  // empty name or a value or sd that is not finite, storing nothing.
  bool finish_job(std::int64_t job_id, int attempt, const std::string& result_json,
                  const std::vector<JobArtifact>& artifacts = {},
                  const std::optional<std::vector<SeriesValue>>& series = std::nullopt);
  bool fail_job(std::int64_t job_id, int attempt, const std::string& error);
  // The holding attempt gives its job back unfinished (its process stops):
  // `queued` again at once, attempts kept; false when it no longer held it.
  bool release_job(std::int64_t job_id, int attempt);
  // Every `running` job (one server on the file, at its start: whatever
  // runs was left by its dead predecessor): `queued` again, or `failed`
  // ("gave up after N attempts") once it has had max_attempts claims.
  // Returns how many were queued again.
  int requeue_running_jobs(int max_attempts = 3);
  // The `running` jobs whose lease has expired (their worker died or
  // stalled; a job without a lease, left by a program before schema v8,
  // counts as expired): `queued` again, attempts kept (the next claim is a
  // new attempt), or `failed` once they have had max_attempts claims. Safe
  // beside live workers of other processes: their leases have not expired.
  struct Requeued {
    int requeued = 0, failed = 0;
  };
  Requeued requeue_expired_jobs(int max_attempts = 3);
  // Queued jobs of the pump and kind whose model or reference version is
  // older than given: `cancelled` (superseded). Returns how many.
  int cancel_superseded_jobs(const std::string& pump_id, const std::string& kind, int model_version,
                             int reference_version);
  bool cancel_job(std::int64_t job_id, const std::string& reason);
  std::optional<Job> find_job(std::int64_t job_id);
  std::optional<Job> find_job(const JobKey& key);
  std::vector<Job> list_jobs(const JobFilter& filter);
  std::int64_t count_jobs(JobStatus status);
  // Jobs by (kind, status) (GET /metrics); one scan of the jobs table.
  std::map<std::pair<std::string, std::string>, std::int64_t> count_jobs_by_kind_and_status();
  // A done job's file, nullopt when it has none of that name.
  std::optional<JobArtifact> find_artifact(std::int64_t job_id, const std::string& name);
  std::vector<std::string> list_artifacts(std::int64_t job_id);

  // --- events (events.h; historian_events.cc) ---
  // Appends an event (GET /api/v1/events on every server) and returns its
  // seq. Inside a WriteBatch it is held until the batch's commit, which
  // writes the batch's events (in the order appended) as its last step,
  // so it commits with what it announces, or not at all, and returns 0:
  // the events' lock is always the last lock a transaction takes
  // (docs/storage.md "Lock order"). Keeps the table bounded (events.h:
  // kEventsKeepRows, kEventsKeep).
  std::int64_t append_event(const std::string& type, const std::string& pump_id, const std::string& data_json);
  // The events after `after_seq`, oldest first, at most `limit` (>= 1).
  std::vector<StoredEvent> events_after(std::int64_t after_seq, int limit);
  // The newest `limit` events held, oldest first.
  std::vector<StoredEvent> recent_events(int limit);
  // The newest seq the table ever gave (0 before schema v8's first writer):
  // not lowered by pruning, so a tail that starts here misses nothing new.
  std::int64_t last_event_seq();
  // The oldest seq still held; nullopt when the table is empty.
  std::optional<std::int64_t> first_event_seq();
  // Deletes all but the newest `keep_rows` events and those older than
  // `older_than` (ISO 8601 UTC). Returns how many went.
  int prune_events(std::int64_t keep_rows, const std::string& older_than);

  // --- trend series (trends.h; historian_trends.cc) ---
  // Points for the done analysis jobs whose run holds none of them (files
  // upgraded from schema 4, or results stored without series): for each
  // run the newest done analysis job's result, through `series_of`.
  // Returns how many runs got their points.
  int backfill_series(const std::function<std::vector<SeriesValue>(const std::string& result_json)>& series_of);
  // The pump's series: those its runs fed, then its monitoring values when
  // it has snapshots ("monitoring.speed_rpm", "monitoring.orbit_major_m.a",
  // ...); by name.
  std::vector<SeriesInfo> list_series(const std::string& pump_id);
  // The series' points in the query's range; nullopt when the pump has no
  // such series. Throws InputError for max_points < 1 or from > to.
  std::optional<Trend> query_trend(const std::string& pump_id, const std::string& name, const TrendQuery& q);
  // The series' points of these runs (e.g. the reference runs), by time.
  std::vector<TrendPoint> run_points(const std::string& pump_id, const std::string& name,
                                     const std::vector<std::string>& run_ids);

  // --- API tokens (service.h; historian_tokens.cc) ---
  // Creates a token of that role and returns its secret (shown once; only
  // its SHA-256 is stored). Throws InputError for an empty or taken name.
  std::string add_token(const std::string& name, Role role);
  // The token's holder, nullopt for an unknown or revoked secret.
  std::optional<TokenInfo> find_token(const std::string& secret);
  std::vector<TokenInfo> list_tokens();
  // False when no active token has that name.
  bool revoke_token(const std::string& name);

  // --- alarms (alarms.h; historian_alarms.cc) ---
  // A new version of the pump's alarm rules (registers the pump if new).
  int put_alarm_rules(const std::string& pump_id, const std::string& rules_json, const std::string& created_by);
  std::optional<AlarmRulesVersion> find_alarm_rules(const std::string& pump_id);
  // Stores alarms, journal entries, memories and the cursor in one write
  // transaction; fills in new alarm ids and the events' seq. Throws
  // InputError when an open alarm of the same pump and rule exists (a second
  // one while active) or an event names no alarm; nothing is stored then.
  void apply_alarm_changes(AlarmChanges& changes);
  // Inside a WriteBatch, before reading what an evaluation or an operator's
  // action of the pump's alarms depends on (its alarms, memories, cursor):
  // waits until no other transaction holds the pump's alarms and holds
  // them until this one ends, so two servers evaluating one pump take
  // turns and the second sees the first's result (docs/storage.md "What
  // guards each write"). PostgreSQL: an advisory lock on the pump; SQLite:
  // nothing (its one writer).
  void lock_pump_alarms(const std::string& pump_id);
  std::optional<AlarmRecord> find_alarm(std::int64_t alarm_id);
  // Newest first.
  std::vector<AlarmRecord> list_alarms(const AlarmFilter& filter);
  // The pump's alarms that are not `normal` (at most one per rule).
  std::vector<AlarmRecord> open_alarms(const std::string& pump_id);
  // Shelved alarms whose shelved_until is at or before `time` (ISO 8601 UTC).
  std::vector<AlarmRecord> expired_shelves(const std::string& time);
  // The alarm's journal, oldest first.
  std::vector<AlarmEvent> alarm_history(std::int64_t alarm_id);
  // The fleet's journal after `after_seq`, oldest first, at most `limit`.
  std::vector<AlarmEvent> alarm_events(std::int64_t after_seq, int limit);
  // Journal entries with from <= time < to (ISO 8601 UTC), oldest first.
  std::vector<AlarmEvent> alarm_events_between(const std::string& from, const std::string& to);
  std::int64_t last_alarm_seq();
  // Active alarms (the condition holds or is latched) by severity, for
  // GET /metrics; severities without one are absent.
  std::map<std::string, std::int64_t> count_active_alarms_by_severity();
  // Each rule's evaluation memory for the pump: (rule, memory).
  std::vector<std::pair<std::string, std::string>> alarm_memories(const std::string& pump_id);
  std::optional<AlarmCursor> find_alarm_cursor(const std::string& pump_id);
  std::vector<AlarmCursor> list_alarm_cursors();
  // The pump's first complete identification run after (started_at, run_id)
  // in that order; the first of all when `after` is empty.
  std::optional<RunInfo> next_run_for_alarms(const std::string& pump_id, const std::optional<std::pair<std::string, std::string>>& after);

  // --- ingest groups (ingest_lease.h; historian_leases.cc) ---
  // Each call is one write transaction; inside a WriteBatch, a savepoint of
  // it (the ingest's commit checks its lease in its own transaction).
  // Registers the group, held by nobody, if it is new, and returns its row.
  // A group held by nobody takes the partitions given. Throws InputError
  // for an empty group or partition list, lease_ms < 1, or a group that is
  // held while registered with other partitions (servers of one group must
  // read the same pumps); nothing changed then.
  IngestLease join_ingest_group(const std::string& group, const std::string& partitions, std::int64_t lease_ms);
  std::optional<IngestLease> find_ingest_lease(const std::string& group);
  std::vector<IngestLease> list_ingest_leases();  // by group
  // Takes the group for `holder` if its row is still as `seen` (holder,
  // epoch, renewals) and covers `partitions`: epoch + 1, lease_ms the new
  // holder's. nullopt (nothing changed) when another server renewed or took
  // it meanwhile, or it covers other partitions.
  std::optional<IngestLease> take_ingest_lease(const IngestLease& seen, const std::string& holder,
                                               const std::string& partitions, std::int64_t lease_ms);
  // The holder (holder, epoch) renews: renewals + 1, renewed_at and
  // expires_at from now. False, nothing changed, when it no longer holds
  // the group (taken over, released).
  bool renew_ingest_lease(const std::string& group, const std::string& holder, std::int64_t epoch,
                          std::int64_t lease_ms);
  // A clean stop: held by nobody, so a standby takes it at once. False when
  // (holder, epoch) no longer held it.
  bool release_ingest_lease(const std::string& group, const std::string& holder, std::int64_t epoch);

  // --- retention (retention.h; historian_retention.cc) ---
  // A new version of the pump's own policy: `policy_json`, an object of
  // kRetentionKeys (checked: InputError naming the key; stored as given).
  // InputError for an unknown pump.
  int put_retention_policy(const std::string& pump_id, const std::string& policy_json, const std::string& created_by);
  // The newest version; nullopt when the pump has set none.
  std::optional<RetentionVersion> find_retention_policy(const std::string& pump_id);
  std::vector<RetentionVersion> list_retention_policies(const std::string& pump_id);  // oldest first
  // The pump's newest policy over `defaults` (the defaults when it has none).
  RetentionPolicy effective_retention_policy(const std::string& pump_id, const RetentionPolicy& defaults);
  RetentionUsage retention_usage(const std::string& pump_id);
  // One sweep over every pump with its effective policy (its own over
  // `defaults`): drops what the policies no longer keep, in transactions of
  // a bounded size, each all or nothing, and finishes drops an earlier sweep
  // left half done. Safe beside ingest, jobs and other sweeps (each drop
  // re-checks its run inside its transaction; the lease keeps a second
  // sweep out: report.skipped). A dry run works on a read connection.
  SweepReport sweep_retention(const RetentionPolicy& defaults, const SweepOptions& options = {});

  // --- reading (either mode) ---
  std::vector<PumpSummary> list_pumps();
  std::optional<PumpSummary> find_pump(const std::string& pump_id);
  std::vector<RunInfo> list_runs(const std::string& pump_id);  // by started_at
  std::optional<RunInfo> find_run(const std::string& run_id);
  std::int64_t count_runs();
  // Snapshots of the pump with time_ns >= since_ns, oldest first, at most
  // `limit` (>= 1).
  std::vector<MonitoringSnapshot> list_monitoring(const std::string& pump_id, std::int64_t since_ns,
                                                  std::int64_t limit);
  // The chunks held, concatenated in seq order: for a complete run exactly
  // the recording's samples.f32. Throws InputError for an unknown run and
  // for a run whose samples retention dropped (naming when).
  std::string read_samples(const std::string& run_id);
  // Same bytes, one call per chunk in seq order, inside one read snapshot;
  // stops early (returning false) when `sink` returns false.
  bool stream_samples(const std::string& run_id,
                      const std::function<bool(std::span<const std::uint8_t>)>& sink);

  // A read snapshot: while it lives, every read on this Historian sees the
  // same committed state (e.g. a run's size and then its bytes).
  class Snapshot {
   public:
    Snapshot(Snapshot&&) noexcept;
    Snapshot& operator=(Snapshot&&) = delete;
    ~Snapshot();

   private:
    friend class Historian;
    explicit Snapshot(Historian* h);
    Historian* h_;
  };
  Snapshot snapshot();

  struct Impl;

 private:
  explicit Historian(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace ambdiag::storage
