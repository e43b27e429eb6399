// The historian's schema in PostgreSQL. SQLite's migrations (schema.cc)
// are the history of files since version 1; a PostgreSQL database is
// created directly at the version it starts at (6, then the later
// migrations, 7 to 10) and from then on
// migrated like a file: a change to the schema is a new entry here AND in
// schema.cc, with the same number (docs/storage.md, "Adding a migration").
//
// Types: text COLLATE "C" (byte order, as SQLite compares text: ORDER BY
// and the (started_at, run_id) cursors give the same answers on both
// whatever the database's locale), bigint for INTEGER, double precision for
// REAL, bytea for BLOB, identity columns where SQLite has INTEGER PRIMARY
// KEY ids. Timestamps stay ISO 8601 text, as in SQLite, except the one
// sample_chunks is partitioned by.
#include "sql/postgres/pg_schema.h"

#include <optional>
#include <string>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "schema.h"

namespace ambdiag::storage::detail {

namespace {

// Append only, as schema.cc.
constexpr Migration kPgMigrations[] = {
    // v6: everything SQLite's migrations 1-6 created, at once.
    {6, R"sql(
CREATE TABLE pumps (
  pump_id     text COLLATE "C" PRIMARY KEY,
  first_seen  text COLLATE "C" NOT NULL
);

CREATE TABLE runs (
  run_id            text COLLATE "C" PRIMARY KEY,
  pump_id           text COLLATE "C" NOT NULL REFERENCES pumps(pump_id),
  kind              text COLLATE "C" NOT NULL,
  started_at        text COLLATE "C" NOT NULL,
  speed_rpm         double precision NOT NULL,
  sample_rate_hz    double precision NOT NULL,
  n_channels        bigint NOT NULL CHECK (n_channels > 0),
  header            text COLLATE "C" NOT NULL,
  status            text COLLATE "C" NOT NULL CHECK (status IN ('receiving', 'complete', 'incomplete')),
  status_reason     text COLLATE "C" NOT NULL DEFAULT '',
  expected_frames   bigint,
  expected_checksum bigint,
  received_chunks   bigint NOT NULL DEFAULT 0,
  received_frames   bigint NOT NULL DEFAULT 0,
  duplicate_chunks  bigint NOT NULL DEFAULT 0,
  created_at        text COLLATE "C" NOT NULL,
  updated_at        text COLLATE "C" NOT NULL,
  ended_at          text COLLATE "C",
  checksum_kind     text COLLATE "C" CHECK (checksum_kind IS NULL OR checksum_kind IN ('fnv1a64', 'xxh64'))
);
CREATE INDEX runs_by_pump ON runs(pump_id, started_at);

CREATE TABLE channels (
  run_id  text COLLATE "C" NOT NULL REFERENCES runs(run_id) ON DELETE CASCADE,
  idx     bigint NOT NULL,
  name    text COLLATE "C" NOT NULL,
  role    text COLLATE "C" NOT NULL,
  unit    text COLLATE "C" NOT NULL,
  input   text COLLATE "C" NOT NULL DEFAULT '',
  PRIMARY KEY (run_id, idx)
);

-- Partitioned by the run's created_at (the server clock at begin_run, the
-- same for every chunk of a run), so that retention can drop whole time
-- ranges (docs/storage.md, "PostgreSQL": partitions). A partition key must
-- be part of the primary key; as it is a function of run_id, the key is
-- still one row per (run_id, seq). Until ranges are added every chunk goes
-- to the default partition. The blobs (float32 samples, which do not
-- compress) are stored out of line without compression (STORAGE EXTERNAL).
CREATE TABLE sample_chunks (
  run_id          text COLLATE "C" NOT NULL REFERENCES runs(run_id) ON DELETE CASCADE,
  seq             bigint NOT NULL CHECK (seq >= 0),
  first_frame     bigint NOT NULL CHECK (first_frame >= 0),
  n_frames        bigint NOT NULL CHECK (n_frames > 0),
  data            bytea NOT NULL,
  run_created_at  timestamptz NOT NULL,
  PRIMARY KEY (run_id, seq, run_created_at)
) PARTITION BY RANGE (run_created_at);
CREATE TABLE sample_chunks_default PARTITION OF sample_chunks DEFAULT;
ALTER TABLE sample_chunks ALTER COLUMN data SET STORAGE EXTERNAL;

CREATE TABLE frfs (
  frf_id      bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
  run_id      text COLLATE "C" NOT NULL REFERENCES runs(run_id) ON DELETE CASCADE,
  method      text COLLATE "C" NOT NULL,
  created_at  text COLLATE "C" NOT NULL,
  data        text COLLATE "C" NOT NULL
);
CREATE INDEX frfs_by_run ON frfs(run_id);

CREATE TABLE features (
  feature_id  bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
  pump_id     text COLLATE "C" NOT NULL REFERENCES pumps(pump_id),
  run_id      text COLLATE "C" REFERENCES runs(run_id) ON DELETE CASCADE,
  name        text COLLATE "C" NOT NULL,
  value       double precision NOT NULL,
  unit        text COLLATE "C" NOT NULL DEFAULT '',
  at          text COLLATE "C" NOT NULL,
  detail      text COLLATE "C"
);
CREATE INDEX features_by_pump ON features(pump_id, name, at);

CREATE TABLE monitoring_snapshots (
  pump_id                 text COLLATE "C" NOT NULL REFERENCES pumps(pump_id),
  time_ns                 bigint NOT NULL,
  received_at             text COLLATE "C" NOT NULL,
  speed_rpm               double precision NOT NULL,
  force_1x_amp_n_ax       double precision NOT NULL,
  force_1x_amp_n_ay       double precision NOT NULL,
  force_1x_amp_n_bx       double precision NOT NULL,
  force_1x_amp_n_by       double precision NOT NULL,
  force_1x_phase_rad_ax   double precision NOT NULL,
  force_1x_phase_rad_ay   double precision NOT NULL,
  force_1x_phase_rad_bx   double precision NOT NULL,
  force_1x_phase_rad_by   double precision NOT NULL,
  force_2x_amp_n_ax       double precision NOT NULL,
  force_2x_amp_n_ay       double precision NOT NULL,
  force_2x_amp_n_bx       double precision NOT NULL,
  force_2x_amp_n_by       double precision NOT NULL,
  force_2x_phase_rad_ax   double precision NOT NULL,
  force_2x_phase_rad_ay   double precision NOT NULL,
  force_2x_phase_rad_bx   double precision NOT NULL,
  force_2x_phase_rad_by   double precision NOT NULL,
  orbit_major_m_a         double precision NOT NULL,
  orbit_major_m_b         double precision NOT NULL,
  orbit_minor_m_a         double precision NOT NULL,
  orbit_minor_m_b         double precision NOT NULL,
  orbit_center_x_m_a      double precision NOT NULL,
  orbit_center_x_m_b      double precision NOT NULL,
  orbit_center_y_m_a      double precision NOT NULL,
  orbit_center_y_m_b      double precision NOT NULL,
  PRIMARY KEY (pump_id, time_ns)
);

CREATE TABLE models (
  pump_id     text COLLATE "C" NOT NULL REFERENCES pumps(pump_id),
  version     bigint NOT NULL CHECK (version >= 1),
  plant_json  text COLLATE "C" NOT NULL,
  created_at  text COLLATE "C" NOT NULL,
  created_by  text COLLATE "C" NOT NULL DEFAULT '',
  comment     text COLLATE "C" NOT NULL DEFAULT '',
  PRIMARY KEY (pump_id, version)
);

CREATE TABLE pump_references (
  pump_id     text COLLATE "C" NOT NULL REFERENCES pumps(pump_id),
  version     bigint NOT NULL CHECK (version >= 1),
  created_at  text COLLATE "C" NOT NULL,
  created_by  text COLLATE "C" NOT NULL DEFAULT '',
  PRIMARY KEY (pump_id, version)
);

CREATE TABLE reference_runs (
  pump_id  text COLLATE "C" NOT NULL,
  version  bigint NOT NULL,
  idx      bigint NOT NULL CHECK (idx >= 0),
  run_id   text COLLATE "C" NOT NULL REFERENCES runs(run_id),
  PRIMARY KEY (pump_id, version, idx),
  UNIQUE (pump_id, version, run_id),
  FOREIGN KEY (pump_id, version) REFERENCES pump_references(pump_id, version)
);

CREATE TABLE jobs (
  job_id             bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
  kind               text COLLATE "C" NOT NULL CHECK (kind <> ''),
  pump_id            text COLLATE "C" NOT NULL CHECK (pump_id <> ''),
  run_id             text COLLATE "C" NOT NULL DEFAULT '',
  model_version      bigint NOT NULL DEFAULT 0,
  reference_version  bigint NOT NULL DEFAULT 0,
  status             text COLLATE "C" NOT NULL CHECK (status IN ('queued', 'running', 'done', 'failed', 'cancelled')),
  progress           double precision NOT NULL DEFAULT 0 CHECK (progress >= 0 AND progress <= 1),
  attempts           bigint NOT NULL DEFAULT 0 CHECK (attempts >= 0),
  params             text COLLATE "C" NOT NULL DEFAULT '{}',
  depends_on         bigint REFERENCES jobs(job_id),
  created_at         text COLLATE "C" NOT NULL,
  started_at         text COLLATE "C",
  finished_at        text COLLATE "C",
  error              text COLLATE "C",
  result             text COLLATE "C",
  worker             text COLLATE "C" NOT NULL DEFAULT '',
  UNIQUE (kind, pump_id, run_id, model_version, reference_version)
);
CREATE INDEX jobs_by_status ON jobs(status, job_id);
CREATE INDEX jobs_by_pump ON jobs(pump_id, job_id);
CREATE INDEX jobs_by_run ON jobs(run_id, job_id);

CREATE TABLE job_artifacts (
  job_id        bigint NOT NULL REFERENCES jobs(job_id) ON DELETE CASCADE,
  name          text COLLATE "C" NOT NULL CHECK (name <> ''),
  content_type  text COLLATE "C" NOT NULL,
  data          bytea NOT NULL,
  PRIMARY KEY (job_id, name)
);

CREATE TABLE tokens (
  name        text COLLATE "C" PRIMARY KEY,
  role        text COLLATE "C" NOT NULL CHECK (role IN ('viewer', 'operator', 'engineer', 'admin')),
  sha256      bytea NOT NULL UNIQUE CHECK (length(sha256) = 32),
  created_at  text COLLATE "C" NOT NULL,
  revoked_at  text COLLATE "C"
);

CREATE TABLE series (
  series_id  bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
  pump_id    text COLLATE "C" NOT NULL REFERENCES pumps(pump_id),
  name       text COLLATE "C" NOT NULL CHECK (name <> ''),
  unit       text COLLATE "C" NOT NULL,
  UNIQUE (pump_id, name)
);

CREATE TABLE series_points (
  series_id  bigint NOT NULL REFERENCES series(series_id),
  time_ns    bigint NOT NULL,
  run_id     text COLLATE "C" NOT NULL REFERENCES runs(run_id) ON DELETE CASCADE,
  value      double precision NOT NULL,
  sd         double precision CHECK (sd IS NULL OR sd >= 0),
  PRIMARY KEY (series_id, time_ns, run_id)
);
CREATE INDEX series_points_by_run ON series_points(run_id, series_id);

CREATE TABLE series_runs (
  run_id  text COLLATE "C" PRIMARY KEY REFERENCES runs(run_id) ON DELETE CASCADE,
  job_id  bigint NOT NULL REFERENCES jobs(job_id)
);

CREATE TABLE alarm_rules (
  pump_id     text COLLATE "C" NOT NULL REFERENCES pumps(pump_id),
  version     bigint NOT NULL CHECK (version >= 1),
  rules_json  text COLLATE "C" NOT NULL,
  created_at  text COLLATE "C" NOT NULL,
  created_by  text COLLATE "C" NOT NULL DEFAULT '',
  PRIMARY KEY (pump_id, version)
);

CREATE TABLE alarms (
  alarm_id           bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
  pump_id            text COLLATE "C" NOT NULL CHECK (pump_id <> ''),
  rule               text COLLATE "C" NOT NULL CHECK (rule <> ''),
  severity           text COLLATE "C" NOT NULL CHECK (severity IN ('low', 'medium', 'high', 'critical')),
  state              text COLLATE "C" NOT NULL CHECK (state IN ('normal', 'unack_active', 'ack_active', 'unack_rtn',
                                                              'shelved', 'suppressed', 'out_of_service')),
  active             bigint NOT NULL CHECK (active IN (0, 1)),
  acknowledged       bigint NOT NULL CHECK (acknowledged IN (0, 1)),
  latched            bigint NOT NULL DEFAULT 0 CHECK (latched IN (0, 1)),
  shelved_until      text COLLATE "C",
  suppressed_reason  text COLLATE "C" NOT NULL DEFAULT '',
  out_of_service     bigint NOT NULL DEFAULT 0 CHECK (out_of_service IN (0, 1)),
  raised_at          text COLLATE "C" NOT NULL,
  cleared_at         text COLLATE "C",
  updated_at         text COLLATE "C" NOT NULL,
  run_id             text COLLATE "C" NOT NULL DEFAULT '',
  message            text COLLATE "C" NOT NULL,
  fault              text COLLATE "C",
  value              double precision
);
CREATE UNIQUE INDEX alarms_open ON alarms(pump_id, rule) WHERE state <> 'normal';
CREATE INDEX alarms_by_pump ON alarms(pump_id, alarm_id);
CREATE INDEX alarms_by_state ON alarms(state, alarm_id);

-- seq: a sequence never hands a number out twice; that seq also grows in
-- commit order (the cursor plant systems poll) is apply_alarm_changes' lock.
CREATE TABLE alarm_events (
  seq        bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
  alarm_id   bigint NOT NULL REFERENCES alarms(alarm_id),
  pump_id    text COLLATE "C" NOT NULL,
  rule       text COLLATE "C" NOT NULL,
  kind       text COLLATE "C" NOT NULL CHECK (kind <> ''),
  time       text COLLATE "C" NOT NULL,
  from_state text COLLATE "C" NOT NULL,
  to_state   text COLLATE "C" NOT NULL,
  by         text COLLATE "C" NOT NULL CHECK (by <> ''),
  comment    text COLLATE "C" NOT NULL DEFAULT '',
  run_id     text COLLATE "C" NOT NULL DEFAULT ''
);
CREATE INDEX alarm_events_by_alarm ON alarm_events(alarm_id, seq);
CREATE INDEX alarm_events_by_time ON alarm_events(time);
CREATE FUNCTION alarm_events_append_only() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
  RAISE EXCEPTION 'alarm_events is append-only';
END
$$;
CREATE TRIGGER alarm_events_no_update BEFORE UPDATE OR DELETE ON alarm_events
  FOR EACH ROW EXECUTE FUNCTION alarm_events_append_only();
CREATE TRIGGER alarm_events_no_truncate BEFORE TRUNCATE ON alarm_events
  FOR EACH STATEMENT EXECUTE FUNCTION alarm_events_append_only();

CREATE TABLE alarm_conditions (
  pump_id  text COLLATE "C" NOT NULL,
  rule     text COLLATE "C" NOT NULL,
  memory   text COLLATE "C" NOT NULL,
  PRIMARY KEY (pump_id, rule)
);

CREATE TABLE alarm_cursors (
  pump_id            text COLLATE "C" PRIMARY KEY,
  started_at         text COLLATE "C" NOT NULL,
  run_id             text COLLATE "C" NOT NULL,
  model_version      bigint NOT NULL,
  reference_version  bigint NOT NULL,
  last_valid_at      text COLLATE "C"
);
)sql"},
    // v7: ingest groups' leases (SQLite's v7, ingest_lease.h). The lease's
    // compare-and-set UPDATEs need nothing more here: the row lock of one
    // makes another wait and then re-check its WHERE on the new row.
    {7, R"sql(
CREATE TABLE ingest_leases (
  ingest_group  text COLLATE "C" PRIMARY KEY CHECK (ingest_group <> ''),
  partitions    text COLLATE "C" NOT NULL CHECK (partitions <> ''),
  holder        text COLLATE "C" NOT NULL DEFAULT '',
  epoch         bigint NOT NULL DEFAULT 0 CHECK (epoch >= 0),
  renewals      bigint NOT NULL DEFAULT 0 CHECK (renewals >= 0),
  lease_ms      bigint NOT NULL CHECK (lease_ms > 0),
  acquired_at   text COLLATE "C",
  renewed_at    text COLLATE "C",
  expires_at    text COLLATE "C",
  created_at    text COLLATE "C" NOT NULL
);
)sql"},
    // v8: job leases and the events table (SQLite's v8). lease_expires_at
    // stays ISO 8601 text of the writing process' clock, as on SQLite
    // (docs/storage.md "Schema v8"). The events' seq is an identity whose
    // sequence starts at the migration's time in microseconds (setval: the
    // next is one more, as after SQLite's sqlite_sequence row); its name is
    // fixed because last_event_seq reads it. That seqs also commit in
    // order is append_event's advisory lock.
    {8, R"sql(
ALTER TABLE jobs ADD COLUMN lease_expires_at text COLLATE "C";
CREATE INDEX jobs_running_by_lease ON jobs(lease_expires_at) WHERE status = 'running';

CREATE TABLE events (
  seq      bigint GENERATED ALWAYS AS IDENTITY (SEQUENCE NAME events_seq_seq) PRIMARY KEY,
  time     text COLLATE "C" NOT NULL,
  type     text COLLATE "C" NOT NULL CHECK (type <> ''),
  pump_id  text COLLATE "C" NOT NULL DEFAULT '',
  data     text COLLATE "C" NOT NULL
);
SELECT setval('events_seq_seq', CAST(extract(epoch FROM clock_timestamp()) * 1000000 AS bigint));
)sql"},
    // v9: retention (SQLite's v9, retention.h; docs/storage.md "Retention").
    // The same columns, indexes and tables; runs_by_created_at finds the
    // runs of one of sample_chunks' day partitions (historian_partitions.cc),
    // which the sweep drops whole when none of its runs is kept.
    {9, R"sql(
ALTER TABLE runs ADD COLUMN samples_state text COLLATE "C" NOT NULL DEFAULT 'held'
  CHECK (samples_state IN ('held', 'dropping', 'dropped'));
ALTER TABLE runs ADD COLUMN samples_dropped_at text COLLATE "C";
ALTER TABLE runs ADD COLUMN samples_dropped_bytes bigint NOT NULL DEFAULT 0 CHECK (samples_dropped_bytes >= 0);
ALTER TABLE runs ADD COLUMN frf_dropped_at text COLLATE "C";
ALTER TABLE runs ADD COLUMN frf_dropped_bytes bigint NOT NULL DEFAULT 0 CHECK (frf_dropped_bytes >= 0);
CREATE INDEX runs_samples_held ON runs(pump_id, created_at) WHERE samples_state = 'held';
CREATE INDEX runs_samples_dropping ON runs(run_id) WHERE samples_state = 'dropping';
CREATE INDEX runs_frf_held ON runs(pump_id, created_at) WHERE frf_dropped_at IS NULL;
CREATE INDEX runs_by_created_at ON runs(created_at);
CREATE INDEX reference_runs_by_run ON reference_runs(run_id);
CREATE INDEX alarms_open_by_run ON alarms(run_id) WHERE state <> 'normal';

CREATE TABLE retention_policies (
  pump_id      text COLLATE "C" NOT NULL REFERENCES pumps(pump_id),
  version      bigint NOT NULL CHECK (version >= 1),
  policy_json  text COLLATE "C" NOT NULL,
  created_at   text COLLATE "C" NOT NULL,
  created_by   text COLLATE "C" NOT NULL DEFAULT '',
  PRIMARY KEY (pump_id, version)
);

CREATE TABLE retention_lease (
  name        text COLLATE "C" PRIMARY KEY,
  holder      text COLLATE "C" NOT NULL,
  expires_at  text COLLATE "C" NOT NULL
);
)sql"},
    // v10: a day partition of sample_chunks goes whole even when a few of
    // its runs are kept (historian_retention.cc, docs/storage.md
    // "PostgreSQL: day partitions"): the sweep first moves the kept runs'
    // chunks to sample_chunks_kept, setting their run_created_at to
    // 1800-01-01 (AMBDIAG_KEPT_CHUNKS_AT, historian_impl.h), a range before
    // any reception time, so no day's drop ever takes it.
    // runs.samples_kept_at says when a run's chunks moved (NULL: they are in
    // its day's partition), so that put_chunks inserts a re-sent chunk of it
    // with the same key and finds the one held (a duplicate), not a new row
    // in another partition. Creating the partition scans
    // sample_chunks_default once (PostgreSQL checks it holds no row of the
    // range; none can, as every run_created_at is a server clock).
    {10, R"sql(
CREATE TABLE sample_chunks_kept PARTITION OF sample_chunks
  FOR VALUES FROM (MINVALUE) TO ('1900-01-01 00:00:00+00');
ALTER TABLE sample_chunks_kept ALTER COLUMN data SET STORAGE EXTERNAL;
ALTER TABLE runs ADD COLUMN samples_kept_at text COLLATE "C";
)sql"},
};

// The mark and version of an ambdiag historian (SQLite: PRAGMA
// application_id and user_version).
constexpr const char* kSchemaTableSql = R"sql(
CREATE TABLE ambdiag_schema (
  application  text NOT NULL CHECK (application = 'ambdiag'),
  version      integer NOT NULL
);
INSERT INTO ambdiag_schema (application, version) VALUES ('ambdiag', 0);
)sql";

// Serialises writers creating or migrating the schema of one database.
constexpr const char* kMigrationLockSql = "SELECT pg_advisory_xact_lock(5, hashtext(current_schema()))";

std::optional<std::string> one_text(PgDb& db, const char* sql) {
  auto s = db.prepare(sql, Fetch::all);
  if (!s->step() || s->col_null(0)) return std::nullopt;
  return s->col_text(0);
}

std::int64_t one_int(PgDb& db, const char* sql) {
  auto s = db.prepare(sql, Fetch::all);
  return s->step() ? s->col_int(0) : 0;
}

}  // namespace

int pg_latest_schema_version() { return kPgMigrations[std::size(kPgMigrations) - 1].version; }

void pg_migrate(PgDb& db, bool read_only) {
  const int latest = pg_latest_schema_version();
  const std::string& where = db.display();
  const auto encoding = one_text(db, "SELECT current_setting('server_encoding')");
  if (encoding != "UTF8")
    throw InputError(where + ": the database's encoding is " + encoding.value_or("?") +
                     "; an ambdiag historian needs UTF8 (CREATE DATABASE ... ENCODING 'UTF8')");
  const auto schema = one_text(db, "SELECT current_schema()");
  if (!schema)
    throw InputError(where + ": no schema to hold the historian (search_path names none that exists)");
  const std::string in = where + " (schema " + *schema + ")";
  const auto version_now = [&]() -> std::optional<int> {
    if (one_int(db, "SELECT count(*) FROM pg_catalog.pg_tables WHERE schemaname = current_schema() "
                    "AND tablename = 'ambdiag_schema'") == 0) {
      if (one_int(db, "SELECT count(*) FROM pg_catalog.pg_class c JOIN pg_catalog.pg_namespace n ON n.oid = "
                      "c.relnamespace WHERE n.nspname = current_schema() AND c.relkind IN ('r', 'p', 'v')") > 0)
        throw InputError(in + ": a database with tables but no ambdiag mark, not an ambdiag historian");
      return std::nullopt;
    }
    const auto v = one_text(db, "SELECT CAST(version AS text) FROM ambdiag_schema WHERE application = 'ambdiag'");
    if (!v) throw InputError(in + ": table ambdiag_schema holds no version, not an ambdiag historian");
    return std::stoi(*v);
  };
  auto version = version_now();
  if (version && *version > latest)
    throw InputError(in + ": schema version " + std::to_string(*version) + " is newer than this program's (" +
                     std::to_string(latest) + "); use a newer ambdiag to open it");
  if (read_only) {
    if (!version)
      throw InputError(in + ": no ambdiag historian here yet; open it once with a writer (ambdiag serve) to create it");
    if (*version < latest)
      throw InputError(in + ": schema version " + std::to_string(*version) + ", this program needs " +
                       std::to_string(latest) + "; open it once with a writer (ambdiag serve) to migrate");
    return;
  }
  if (version == latest) return;
  // All of it in one transaction (PostgreSQL's DDL is transactional): a
  // reader never sees a schema half made; the lock makes a second writer
  // starting at the same time wait, then find the work done.
  Transaction tx(db, Transaction::Kind::write);
  db.exec(kMigrationLockSql, "migration lock");
  version = version_now();
  if (!version) {
    db.exec(kSchemaTableSql, "create the schema");
    version = 0;
  }
  for (const auto& m : kPgMigrations) {
    if (m.version <= *version) continue;
    db.exec(m.sql, "migration");
    db.exec(("UPDATE ambdiag_schema SET version = " + std::to_string(m.version)).c_str(), "migration");
  }
  tx.commit();
}

}  // namespace ambdiag::storage::detail
