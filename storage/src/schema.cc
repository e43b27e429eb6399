#include "schema.h"

#include <string>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"

namespace ambdiag::storage::detail {

namespace {

// Append only: a released migration is never edited, a change is a new one.
// STRICT tables make SQLite refuse values of the wrong type.
constexpr Migration kMigrations[] = {
    {1, R"sql(
CREATE TABLE pumps (
  pump_id     TEXT PRIMARY KEY,
  first_seen  TEXT NOT NULL
) STRICT;

CREATE TABLE runs (
  run_id            TEXT PRIMARY KEY,
  pump_id           TEXT NOT NULL REFERENCES pumps(pump_id),
  kind              TEXT NOT NULL,
  started_at        TEXT NOT NULL,
  speed_rpm         REAL NOT NULL,
  sample_rate_hz    REAL NOT NULL,
  n_channels        INTEGER NOT NULL CHECK (n_channels > 0),
  header            TEXT NOT NULL,
  status            TEXT NOT NULL CHECK (status IN ('receiving', 'complete', 'incomplete')),
  status_reason     TEXT NOT NULL DEFAULT '',
  expected_frames   INTEGER,
  expected_checksum INTEGER,
  received_chunks   INTEGER NOT NULL DEFAULT 0,
  received_frames   INTEGER NOT NULL DEFAULT 0,
  duplicate_chunks  INTEGER NOT NULL DEFAULT 0,
  created_at        TEXT NOT NULL,
  updated_at        TEXT NOT NULL,
  ended_at          TEXT
) STRICT;
CREATE INDEX runs_by_pump ON runs(pump_id, started_at);

CREATE TABLE channels (
  run_id  TEXT NOT NULL REFERENCES runs(run_id) ON DELETE CASCADE,
  idx     INTEGER NOT NULL,
  name    TEXT NOT NULL,
  role    TEXT NOT NULL,
  unit    TEXT NOT NULL,
  input   TEXT NOT NULL DEFAULT '',
  PRIMARY KEY (run_id, idx)
) STRICT, WITHOUT ROWID;

CREATE TABLE sample_chunks (
  run_id       TEXT NOT NULL REFERENCES runs(run_id) ON DELETE CASCADE,
  seq          INTEGER NOT NULL CHECK (seq >= 0),
  first_frame  INTEGER NOT NULL CHECK (first_frame >= 0),
  n_frames     INTEGER NOT NULL CHECK (n_frames > 0),
  data         BLOB NOT NULL,
  PRIMARY KEY (run_id, seq)
) STRICT;

CREATE TABLE frfs (
  frf_id      INTEGER PRIMARY KEY,
  run_id      TEXT NOT NULL REFERENCES runs(run_id) ON DELETE CASCADE,
  method      TEXT NOT NULL,
  created_at  TEXT NOT NULL,
  data        TEXT NOT NULL
) STRICT;
CREATE INDEX frfs_by_run ON frfs(run_id);

CREATE TABLE features (
  feature_id  INTEGER PRIMARY KEY,
  pump_id     TEXT NOT NULL REFERENCES pumps(pump_id),
  run_id      TEXT REFERENCES runs(run_id) ON DELETE CASCADE,
  name        TEXT NOT NULL,
  value       REAL NOT NULL,
  unit        TEXT NOT NULL DEFAULT '',
  at          TEXT NOT NULL,
  detail      TEXT
) STRICT;
CREATE INDEX features_by_pump ON features(pump_id, name, at);

CREATE TABLE alarms (
  alarm_id      INTEGER PRIMARY KEY,
  pump_id       TEXT NOT NULL REFERENCES pumps(pump_id),
  run_id        TEXT REFERENCES runs(run_id) ON DELETE SET NULL,
  raised_at     TEXT NOT NULL,
  severity      TEXT NOT NULL,
  kind          TEXT NOT NULL,
  message       TEXT NOT NULL,
  detail        TEXT,
  acknowledged  INTEGER NOT NULL DEFAULT 0
) STRICT;
CREATE INDEX alarms_by_pump ON alarms(pump_id, raised_at);

CREATE TABLE jobs (
  job_id      TEXT PRIMARY KEY,
  kind        TEXT NOT NULL,
  status      TEXT NOT NULL,
  params      TEXT NOT NULL,
  result      TEXT,
  error       TEXT,
  created_at  TEXT NOT NULL,
  updated_at  TEXT NOT NULL
) STRICT;
)sql"},
    // v2: monitoring snapshots (proto MonitoringSnapshot), one row per pump
    // and agent time; arrays spread into columns so trends are plain SQL.
    {2, R"sql(
CREATE TABLE monitoring_snapshots (
  pump_id                 TEXT NOT NULL REFERENCES pumps(pump_id),
  time_ns                 INTEGER NOT NULL,
  received_at             TEXT NOT NULL,
  speed_rpm               REAL NOT NULL,
  force_1x_amp_n_ax       REAL NOT NULL,
  force_1x_amp_n_ay       REAL NOT NULL,
  force_1x_amp_n_bx       REAL NOT NULL,
  force_1x_amp_n_by       REAL NOT NULL,
  force_1x_phase_rad_ax   REAL NOT NULL,
  force_1x_phase_rad_ay   REAL NOT NULL,
  force_1x_phase_rad_bx   REAL NOT NULL,
  force_1x_phase_rad_by   REAL NOT NULL,
  force_2x_amp_n_ax       REAL NOT NULL,
  force_2x_amp_n_ay       REAL NOT NULL,
  force_2x_amp_n_bx       REAL NOT NULL,
  force_2x_amp_n_by       REAL NOT NULL,
  force_2x_phase_rad_ax   REAL NOT NULL,
  force_2x_phase_rad_ay   REAL NOT NULL,
  force_2x_phase_rad_bx   REAL NOT NULL,
  force_2x_phase_rad_by   REAL NOT NULL,
  orbit_major_m_a         REAL NOT NULL,
  orbit_major_m_b         REAL NOT NULL,
  orbit_minor_m_a         REAL NOT NULL,
  orbit_minor_m_b         REAL NOT NULL,
  orbit_center_x_m_a      REAL NOT NULL,
  orbit_center_x_m_b      REAL NOT NULL,
  orbit_center_y_m_a      REAL NOT NULL,
  orbit_center_y_m_b      REAL NOT NULL,
  PRIMARY KEY (pump_id, time_ns)
) STRICT, WITHOUT ROWID;
)sql"},
    // v3: how the run end's checksum is computed (core/checksum.h names), so
    // that expected_checksum can be checked by a reader; NULL for runs that
    // ended before v3 (their kind was not kept).
    {3, R"sql(
ALTER TABLE runs ADD COLUMN checksum_kind TEXT CHECK (checksum_kind IS NULL OR checksum_kind IN ('fnv1a64', 'xxh64'));
)sql"},
    // v4: the service store (storage/service.h). Pumps' plant models and
    // references, every version kept; the job queue with its results and
    // files; API tokens by their SHA-256. v1's `jobs` never held a row (no
    // program wrote it): replaced by the queue's own table. Jobs name pumps
    // and runs without foreign keys: a job's row is its history and outlives
    // nothing it points to, and an enqueue must not fail on a constraint.
    {4, R"sql(
DROP TABLE jobs;

CREATE TABLE models (
  pump_id     TEXT NOT NULL REFERENCES pumps(pump_id),
  version     INTEGER NOT NULL CHECK (version >= 1),
  plant_json  TEXT NOT NULL,
  created_at  TEXT NOT NULL,
  created_by  TEXT NOT NULL DEFAULT '',
  comment     TEXT NOT NULL DEFAULT '',
  PRIMARY KEY (pump_id, version)
) STRICT;

CREATE TABLE pump_references (
  pump_id     TEXT NOT NULL REFERENCES pumps(pump_id),
  version     INTEGER NOT NULL CHECK (version >= 1),
  created_at  TEXT NOT NULL,
  created_by  TEXT NOT NULL DEFAULT '',
  PRIMARY KEY (pump_id, version)
) STRICT, WITHOUT ROWID;

CREATE TABLE reference_runs (
  pump_id  TEXT NOT NULL,
  version  INTEGER NOT NULL,
  idx      INTEGER NOT NULL CHECK (idx >= 0),
  run_id   TEXT NOT NULL REFERENCES runs(run_id),
  PRIMARY KEY (pump_id, version, idx),
  UNIQUE (pump_id, version, run_id),
  FOREIGN KEY (pump_id, version) REFERENCES pump_references(pump_id, version)
) STRICT, WITHOUT ROWID;

CREATE TABLE jobs (
  job_id             INTEGER PRIMARY KEY AUTOINCREMENT,
  kind               TEXT NOT NULL CHECK (kind <> ''),
  pump_id            TEXT NOT NULL CHECK (pump_id <> ''),
  run_id             TEXT NOT NULL DEFAULT '',
  model_version      INTEGER NOT NULL DEFAULT 0,
  reference_version  INTEGER NOT NULL DEFAULT 0,
  status             TEXT NOT NULL CHECK (status IN ('queued', 'running', 'done', 'failed', 'cancelled')),
  progress           REAL NOT NULL DEFAULT 0 CHECK (progress >= 0 AND progress <= 1),
  attempts           INTEGER NOT NULL DEFAULT 0 CHECK (attempts >= 0),
  params             TEXT NOT NULL DEFAULT '{}',
  depends_on         INTEGER REFERENCES jobs(job_id),
  created_at         TEXT NOT NULL,
  started_at         TEXT,
  finished_at        TEXT,
  error              TEXT,
  result             TEXT,
  worker             TEXT NOT NULL DEFAULT '',
  UNIQUE (kind, pump_id, run_id, model_version, reference_version)
) STRICT;
CREATE INDEX jobs_by_status ON jobs(status, job_id);
CREATE INDEX jobs_by_pump ON jobs(pump_id, job_id);
CREATE INDEX jobs_by_run ON jobs(run_id, job_id);

CREATE TABLE job_artifacts (
  job_id        INTEGER NOT NULL REFERENCES jobs(job_id) ON DELETE CASCADE,
  name          TEXT NOT NULL CHECK (name <> ''),
  content_type  TEXT NOT NULL,
  data          BLOB NOT NULL,
  PRIMARY KEY (job_id, name)
) STRICT;

CREATE TABLE tokens (
  name        TEXT PRIMARY KEY,
  role        TEXT NOT NULL CHECK (role IN ('viewer', 'operator', 'engineer', 'admin')),
  sha256      BLOB NOT NULL UNIQUE CHECK (length(sha256) = 32),
  created_at  TEXT NOT NULL,
  revoked_at  TEXT
) STRICT;
)sql"},
    // v5: trend series (trends.h). A catalogue of each pump's series, fed
    // by its runs' analyses, and their points: one per (series, run), at the
    // run's started_at in ns, clustered by (series, time) so a range of a
    // series is one index walk. series_runs says which analysis job's values
    // a run's points are (the newest done one replaces the older). Monitoring
    // values are not copied here: monitoring_snapshots is already keyed by
    // (pump_id, time_ns). The points of done analyses stored before v5 are
    // filled by the server at its start (Historian::backfill_series): which
    // values a result gives is the server's code, not SQL.
    {5, R"sql(
CREATE TABLE series (
  series_id  INTEGER PRIMARY KEY,
  pump_id    TEXT NOT NULL REFERENCES pumps(pump_id),
  name       TEXT NOT NULL CHECK (name <> ''),
  unit       TEXT NOT NULL,
  UNIQUE (pump_id, name)
) STRICT;

CREATE TABLE series_points (
  series_id  INTEGER NOT NULL REFERENCES series(series_id),
  time_ns    INTEGER NOT NULL,
  run_id     TEXT NOT NULL REFERENCES runs(run_id) ON DELETE CASCADE,
  value      REAL NOT NULL,
  sd         REAL CHECK (sd IS NULL OR sd >= 0),
  PRIMARY KEY (series_id, time_ns, run_id)
) STRICT, WITHOUT ROWID;
CREATE INDEX series_points_by_run ON series_points(run_id, series_id);

CREATE TABLE series_runs (
  run_id  TEXT PRIMARY KEY REFERENCES runs(run_id) ON DELETE CASCADE,
  job_id  INTEGER NOT NULL REFERENCES jobs(job_id)
) STRICT, WITHOUT ROWID;
)sql"},
    // v6: alarms (server/src/alarms; docs/service.md "Alarms"). v1's `alarms`
    // never held a row (no program wrote it): replaced. Per pump: the rule
    // versions, each alarm (one open per pump and rule: the partial unique
    // index), the journal of every transition (append only: triggers refuse
    // UPDATE and DELETE; seq is the cursor plant systems poll), each rule's
    // evaluation memory and the evaluation cursor (the last run evaluated,
    // so an evaluation interrupted by a crash is done at the next start).
    {6, R"sql(
DROP INDEX alarms_by_pump;
DROP TABLE alarms;

CREATE TABLE alarm_rules (
  pump_id     TEXT NOT NULL REFERENCES pumps(pump_id),
  version     INTEGER NOT NULL CHECK (version >= 1),
  rules_json  TEXT NOT NULL,
  created_at  TEXT NOT NULL,
  created_by  TEXT NOT NULL DEFAULT '',
  PRIMARY KEY (pump_id, version)
) STRICT;

CREATE TABLE alarms (
  alarm_id           INTEGER PRIMARY KEY AUTOINCREMENT,
  pump_id            TEXT NOT NULL CHECK (pump_id <> ''),
  rule               TEXT NOT NULL CHECK (rule <> ''),
  severity           TEXT NOT NULL CHECK (severity IN ('low', 'medium', 'high', 'critical')),
  state              TEXT NOT NULL CHECK (state IN ('normal', 'unack_active', 'ack_active', 'unack_rtn', 'shelved',
                                                    'suppressed', 'out_of_service')),
  active             INTEGER NOT NULL CHECK (active IN (0, 1)),
  acknowledged       INTEGER NOT NULL CHECK (acknowledged IN (0, 1)),
  latched            INTEGER NOT NULL DEFAULT 0 CHECK (latched IN (0, 1)),
  shelved_until      TEXT,
  suppressed_reason  TEXT NOT NULL DEFAULT '',
  out_of_service     INTEGER NOT NULL DEFAULT 0 CHECK (out_of_service IN (0, 1)),
  raised_at          TEXT NOT NULL,
  cleared_at         TEXT,
  updated_at         TEXT NOT NULL,
  run_id             TEXT NOT NULL DEFAULT '',
  message            TEXT NOT NULL,
  fault              TEXT,
  value              REAL
) STRICT;
CREATE UNIQUE INDEX alarms_open ON alarms(pump_id, rule) WHERE state <> 'normal';
CREATE INDEX alarms_by_pump ON alarms(pump_id, alarm_id);
CREATE INDEX alarms_by_state ON alarms(state, alarm_id);

CREATE TABLE alarm_events (
  seq       INTEGER PRIMARY KEY AUTOINCREMENT,
  alarm_id  INTEGER NOT NULL REFERENCES alarms(alarm_id),
  pump_id   TEXT NOT NULL,
  rule      TEXT NOT NULL,
  kind      TEXT NOT NULL CHECK (kind <> ''),
  time      TEXT NOT NULL,
  from_state TEXT NOT NULL,
  to_state  TEXT NOT NULL,
  by        TEXT NOT NULL CHECK (by <> ''),
  comment   TEXT NOT NULL DEFAULT '',
  run_id    TEXT NOT NULL DEFAULT ''
) STRICT;
CREATE INDEX alarm_events_by_alarm ON alarm_events(alarm_id, seq);
CREATE INDEX alarm_events_by_time ON alarm_events(time);
CREATE TRIGGER alarm_events_no_update BEFORE UPDATE ON alarm_events
BEGIN SELECT RAISE(ABORT, 'alarm_events is append-only'); END;
CREATE TRIGGER alarm_events_no_delete BEFORE DELETE ON alarm_events
BEGIN SELECT RAISE(ABORT, 'alarm_events is append-only'); END;

CREATE TABLE alarm_conditions (
  pump_id  TEXT NOT NULL,
  rule     TEXT NOT NULL,
  memory   TEXT NOT NULL,
  PRIMARY KEY (pump_id, rule)
) STRICT, WITHOUT ROWID;

CREATE TABLE alarm_cursors (
  pump_id            TEXT PRIMARY KEY,
  started_at         TEXT NOT NULL,
  run_id             TEXT NOT NULL,
  model_version      INTEGER NOT NULL,
  reference_version  INTEGER NOT NULL,
  last_valid_at      TEXT
) STRICT;
)sql"},
    // v7: ingest groups (docs/streaming.md "Several servers: ingest groups and
    // failover"). One row per group: the DDS partitions it covers, the
    // process holding it, the fencing epoch (+1 at each new holder; every
    // ingest commit checks it in its own transaction) and a renewal count
    // standbys watch: a holder that stops renewing for its lease is taken
    // over. Times are the holder's clock, for people only: no standby
    // compares clocks. Plain SQL, the same on PostgreSQL.
    {7, R"sql(
CREATE TABLE ingest_leases (
  ingest_group  TEXT PRIMARY KEY CHECK (ingest_group <> ''),
  partitions    TEXT NOT NULL CHECK (partitions <> ''),
  holder        TEXT NOT NULL DEFAULT '',
  epoch         INTEGER NOT NULL DEFAULT 0 CHECK (epoch >= 0),
  renewals      INTEGER NOT NULL DEFAULT 0 CHECK (renewals >= 0),
  lease_ms      INTEGER NOT NULL CHECK (lease_ms > 0),
  acquired_at   TEXT,
  renewed_at    TEXT,
  expires_at    TEXT,
  created_at    TEXT NOT NULL
) STRICT;
)sql"},
    // v8: several servers on one database (docs/service.md "Several
    // servers"). A running job's lease: the server clock (ISO 8601 UTC with
    // milliseconds, so text order is time order) until which its attempt
    // holds it; renewed by the worker, and an expired one is queued again by
    // any analysis process (the partial index finds them without a scan).
    // The events table is what GET /api/v1/events streams on every server:
    // written in the transaction of what it announces, tailed by each REST
    // process by seq. The sequence starts at the migration's time in
    // microseconds, so an event id of another (older) database is never
    // mistaken for one of this database's.
    {8, R"sql(
ALTER TABLE jobs ADD COLUMN lease_expires_at TEXT;
CREATE INDEX jobs_running_by_lease ON jobs(lease_expires_at) WHERE status = 'running';

CREATE TABLE events (
  seq      INTEGER PRIMARY KEY AUTOINCREMENT,
  time     TEXT NOT NULL,
  type     TEXT NOT NULL CHECK (type <> ''),
  pump_id  TEXT NOT NULL DEFAULT '',
  data     TEXT NOT NULL
) STRICT;
INSERT INTO sqlite_sequence (name, seq)
VALUES ('events', CAST((julianday('now') - 2440587.5) * 86400000000.0 AS INTEGER));
)sql"},
    // v9: retention (retention.h; docs/storage.md "Retention"). What a sweep
    // dropped of each run stays on the run's row, so the run stays listed:
    // samples_state goes held -> dropping (marked, chunks being deleted in
    // transactions of a bounded size) -> dropped; frf_dropped_at marks the
    // analyses' files gone. The partial indexes hold only the runs a sweep
    // still looks at (samples held, a drop to finish, files held), so a sweep
    // never walks the runs it is done with. A run is kept while a reference
    // version, an open alarm or a queued or running job names it: indexes
    // to ask that by run. Each pump's policy is versioned like its models;
    // the lease lets one sweep run at a time on a database.
    {9, R"sql(
ALTER TABLE runs ADD COLUMN samples_state TEXT NOT NULL DEFAULT 'held'
  CHECK (samples_state IN ('held', 'dropping', 'dropped'));
ALTER TABLE runs ADD COLUMN samples_dropped_at TEXT;
ALTER TABLE runs ADD COLUMN samples_dropped_bytes INTEGER NOT NULL DEFAULT 0 CHECK (samples_dropped_bytes >= 0);
ALTER TABLE runs ADD COLUMN frf_dropped_at TEXT;
ALTER TABLE runs ADD COLUMN frf_dropped_bytes INTEGER NOT NULL DEFAULT 0 CHECK (frf_dropped_bytes >= 0);
CREATE INDEX runs_samples_held ON runs(pump_id, created_at) WHERE samples_state = 'held';
CREATE INDEX runs_samples_dropping ON runs(run_id) WHERE samples_state = 'dropping';
CREATE INDEX runs_frf_held ON runs(pump_id, created_at) WHERE frf_dropped_at IS NULL;
CREATE INDEX reference_runs_by_run ON reference_runs(run_id);
CREATE INDEX alarms_open_by_run ON alarms(run_id) WHERE state <> 'normal';

CREATE TABLE retention_policies (
  pump_id      TEXT NOT NULL REFERENCES pumps(pump_id),
  version      INTEGER NOT NULL CHECK (version >= 1),
  policy_json  TEXT NOT NULL,
  created_at   TEXT NOT NULL,
  created_by   TEXT NOT NULL DEFAULT '',
  PRIMARY KEY (pump_id, version)
) STRICT;

CREATE TABLE retention_lease (
  name        TEXT PRIMARY KEY,
  holder      TEXT NOT NULL,
  expires_at  TEXT NOT NULL
) STRICT;
)sql"},
    // v10: nothing changes in a file. PostgreSQL's v10 (pg_schema.cc) adds
    // the partition sample_chunks_kept and runs.samples_kept_at, which only
    // its day partitions need: a file has no partitions, its retention
    // deletes run by run. The two backends keep one version number
    // (historian.cc checks), so a file gets a version that changes nothing.
    {10, "SELECT 1;"},
};

int pragma_int(Db& db, const char* sql) {
  SqliteStmt s(db, sql);
  return s.step() ? static_cast<int>(s.col_int(0)) : 0;
}

}  // namespace

int latest_schema_version() { return kMigrations[std::size(kMigrations) - 1].version; }

void set_pragmas(Db& db, bool read_only) {
  db.check(sqlite3_busy_timeout(db.get(), 10000), "busy_timeout");
  // A reader must not turn a rollback-journal file into WAL behind a writer's back.
  if (!read_only) {
    // SQLite's default 4 KiB pages. 64 KiB pages made inserts of 30 KiB
    // chunks 2.3x faster; they were turned off for a REST hang that turned
    // out not to be SQLite's (docs/storage.md, page_size).
    SqliteStmt wal(db, "PRAGMA journal_mode = WAL");
    if (!wal.step() || wal.col_text(0) != "wal")
      throw StorageError(db.path() + ": cannot switch to WAL (needs a local file system)");
  }
  db.exec(
      "PRAGMA synchronous = NORMAL;"  // WAL: durable at checkpoint, consistent always
      "PRAGMA temp_store = MEMORY;"
      "PRAGMA secure_delete = OFF;"     // Debian builds it ON: no zeroing of freed pages
      "PRAGMA foreign_keys = ON;",
      "pragmas");
  // KiB. The writer's 64 MiB holds a batch of chunks and the indexes' hot
  // pages; readers (one per REST worker) stream blobs through and need less.
  db.exec(read_only ? "PRAGMA cache_size = -8192" : "PRAGMA cache_size = -65536", "pragmas");
  if (read_only) db.exec("PRAGMA query_only = ON", "pragmas");
}

void migrate(Db& db, bool read_only) {
  const int latest = latest_schema_version();
  // The first read of the file: a garbage file fails here with "not a database".
  const int app_id = pragma_int(db, "PRAGMA application_id");
  int version = pragma_int(db, "PRAGMA user_version");
  if (app_id != 0 && app_id != kApplicationId)
    throw InputError(db.path() + ": an SQLite database of another application (application_id " +
                     std::to_string(app_id) + "), not an ambdiag historian");
  if (version > latest)
    throw InputError(db.path() + ": schema version " + std::to_string(version) +
                     " is newer than this program's (" + std::to_string(latest) +
                     "); use a newer ambdiag to open it");
  if (app_id == 0 && pragma_int(db, "SELECT count(*) FROM sqlite_schema") > 0)
    throw InputError(db.path() + ": an SQLite database with tables but no ambdiag mark, not an ambdiag historian");
  if (read_only) {
    if (version < latest)
      throw InputError(db.path() + ": schema version " + std::to_string(version) + ", this program needs " +
                       std::to_string(latest) + "; open it once with a writer (ambdiag serve) to migrate");
    return;
  }
  // Every missing migration in one transaction: a reader opening the file
  // meanwhile never sees it half way (e.g. at v1 while this writer needs v2).
  Transaction tx(db, Transaction::Kind::write);
  version = pragma_int(db, "PRAGMA user_version");  // another writer may have migrated meanwhile
  if (version >= latest) return;
  for (const auto& m : kMigrations) {
    if (m.version <= version) continue;
    db.exec(m.sql, "migration");
    // PRAGMA takes no parameters; the values are this program's constants.
    db.exec(("PRAGMA user_version = " + std::to_string(m.version) + ";PRAGMA application_id = " +
             std::to_string(kApplicationId))
                .c_str(),
            "migration");
  }
  tx.commit();
}

}  // namespace ambdiag::storage::detail
