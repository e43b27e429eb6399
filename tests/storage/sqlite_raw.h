// Plain SQLite C API access for the historian tests: inspect or tamper with
// a file behind the Historian's back.
#pragma once

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cstdint>
#include <string>

namespace ambdiag::storage {

// Runs one SQL statement with the plain C API, to inspect or tamper with a file.
inline std::int64_t raw_query_int(const std::string& path, const char* sql) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* s = nullptr;
  EXPECT_EQ(sqlite3_prepare_v2(db, sql, -1, &s, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
  std::int64_t v = -1;
  if (sqlite3_step(s) == SQLITE_ROW) v = sqlite3_column_int64(s, 0);
  sqlite3_finalize(s);
  sqlite3_close(db);
  return v;
}

// `PRAGMA integrity_check` of the file: "ok" when it is consistent.
inline std::string raw_integrity_check(const std::string& path) {
  sqlite3* db = nullptr;
  sqlite3_open(path.c_str(), &db);
  sqlite3_stmt* s = nullptr;
  sqlite3_prepare_v2(db, "PRAGMA integrity_check", -1, &s, nullptr);
  std::string r = sqlite3_step(s) == SQLITE_ROW ? reinterpret_cast<const char*>(sqlite3_column_text(s, 0)) : "?";
  sqlite3_finalize(s);
  sqlite3_close(db);
  return r;
}

inline void raw_exec(const std::string& path, const char* sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, sql, nullptr, nullptr, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
  sqlite3_close(db);
}

// Undoes migration 9 (retention): its tables, indexes and the runs' columns.
inline constexpr const char* kUndoRetentionV9Sql =
    "DROP TABLE retention_lease; DROP TABLE retention_policies; DROP INDEX alarms_open_by_run; "
    "DROP INDEX reference_runs_by_run; DROP INDEX runs_frf_held; DROP INDEX runs_samples_dropping; "
    "DROP INDEX runs_samples_held; ALTER TABLE runs DROP COLUMN frf_dropped_bytes; "
    "ALTER TABLE runs DROP COLUMN frf_dropped_at; ALTER TABLE runs DROP COLUMN samples_dropped_bytes; "
    "ALTER TABLE runs DROP COLUMN samples_dropped_at; ALTER TABLE runs DROP COLUMN samples_state;";

// Undoes migration 8 (job leases, the events table).
inline constexpr const char* kUndoLeasesEventsV8Sql =
    "DROP TABLE events; DELETE FROM sqlite_sequence WHERE name = 'events'; DROP INDEX jobs_running_by_lease; "
    "ALTER TABLE jobs DROP COLUMN lease_expires_at;";

// Undoes migration 7 (ingest groups' leases).
inline constexpr const char* kUndoIngestLeasesV7Sql = "DROP TABLE ingest_leases;";

// Undoes migration 6 (alarms) in SQL, back to v1's unused `alarms` table:
// for the tests that take a file back to an older schema version.
inline constexpr const char* kUndoAlarmsV6Sql =
    "DROP TABLE alarm_events; DROP TABLE alarms; DROP TABLE alarm_rules; DROP TABLE alarm_conditions; "
    "DROP TABLE alarm_cursors; CREATE TABLE alarms (alarm_id INTEGER PRIMARY KEY, pump_id TEXT NOT NULL, "
    "raised_at TEXT NOT NULL, severity TEXT NOT NULL, kind TEXT NOT NULL, message TEXT NOT NULL) STRICT; "
    "CREATE INDEX alarms_by_pump ON alarms(pump_id, raised_at);";

// Undoes migration 5 (trend series).
inline constexpr const char* kUndoTrendsV5Sql = "DROP TABLE series_runs; DROP TABLE series_points; DROP TABLE series;";

// Undoes migration 4 (the analysis service's tables), back to v1's unused
// jobs table.
inline constexpr const char* kUndoServiceV4Sql =
    "DROP TABLE job_artifacts; DROP TABLE jobs; DROP TABLE tokens; DROP TABLE reference_runs; "
    "DROP TABLE pump_references; DROP TABLE models; "
    "CREATE TABLE jobs (job_id TEXT PRIMARY KEY, kind TEXT NOT NULL, status TEXT NOT NULL, params TEXT NOT "
    "NULL, result TEXT, error TEXT, created_at TEXT NOT NULL, updated_at TEXT NOT NULL) STRICT;";

// A file of the current schema taken back to what migration `version`
// (3, 4, 6, 7 or 8) left, for the tests of upgrades.
inline void downgrade_schema(const std::string& path, int version) {
  if (version < 9) raw_exec(path, kUndoRetentionV9Sql);
  if (version < 8) raw_exec(path, kUndoLeasesEventsV8Sql);
  if (version < 7) raw_exec(path, kUndoIngestLeasesV7Sql);
  if (version < 6) raw_exec(path, kUndoAlarmsV6Sql);
  if (version < 5) raw_exec(path, kUndoTrendsV5Sql);
  if (version < 4) raw_exec(path, kUndoServiceV4Sql);
  raw_exec(path, ("PRAGMA user_version = " + std::to_string(version) + ";").c_str());
}

// Runs SQL that should fail: SQLite's error message, "" when it succeeded.
inline std::string raw_exec_error(const std::string& path, const char* sql) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  char* err = nullptr;
  const int rc = sqlite3_exec(db, sql, nullptr, nullptr, &err);
  std::string msg = rc == SQLITE_OK ? "" : (err ? err : "error");
  sqlite3_free(err);
  sqlite3_close(db);
  return msg;
}

}  // namespace ambdiag::storage
