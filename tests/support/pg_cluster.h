// A throwaway PostgreSQL cluster for the tests: initdb into a folder under
// /tmp, the server on a Unix socket in that folder only (no TCP: nothing
// to collide with other test runs), fsync off. As root (CI) the server runs
// as the `postgres` system user, which refuses to run as root.
//
// One cluster serves a whole ctest run: the fixture tests
// postgres_cluster_start / postgres_cluster_stop (tests/CMakeLists.txt)
// run `ambdiag-test-pg start|stop` on the build's cluster folder, and each
// test process attaches to it. A test binary run by hand starts its own,
// and stops it when its tests end. Each test gets a schema of its own.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

namespace ambdiag::testing {

class PgCluster {
 public:
  // initdb into the folder (whatever was there is removed) and start.
  // Throws std::runtime_error saying what to install when PostgreSQL's
  // programs are missing, or what failed (with the server's log).
  // `durable`: fsync on, as a production server (benchmarks); the tests'
  // cluster runs without.
  static PgCluster start(const std::filesystem::path& dir, bool durable = false);
  // The cluster started in `dir`, if it runs and accepts connections.
  static std::optional<PgCluster> attach(const std::filesystem::path& dir);
  // Stops the server at once and removes the folder.
  static void stop(const std::filesystem::path& dir);
  // `pg_ctl restart -m MODE` of the cluster in `dir` (fast: clients are
  // disconnected and the server shuts down cleanly; immediate: it stops
  // as a crash would, and recovers from its log at the start); returns
  // once it accepts connections again. Throws with the server's log.
  static void restart(const std::filesystem::path& dir, const std::string& mode);

  // A streaming standby of `primary` in `dir`, started: pg_basebackup -R
  // over a physical replication slot `name` (so the primary keeps the WAL
  // the standby has not received: without one, a bulk ingest outruns it
  // and its WAL is recycled), application_name `name` for the primary's
  // synchronous_standby_names.
  static PgCluster start_standby(const std::filesystem::path& dir, const PgCluster& primary, const std::string& name);

  // kill -9 of the server's postmaster: the database host's crash.
  void crash() const;
  // Stops the server at once (pg_ctl stop -m immediate), keeping its
  // folder; start_again() starts it on that folder.
  void shut_down() const;
  void start_again() const;
  // pg_ctl promote of a standby; returns once it accepts writes.
  void promote() const;

  const std::filesystem::path& dir() const { return dir_; }
  // A URI of the cluster's `postgres` database, as superuser.
  std::string uri() const;
  // A new, empty schema and a URI whose search_path is that schema.
  std::string fresh_schema_uri(const std::string& name) const;

 private:
  explicit PgCluster(std::filesystem::path dir) : dir_(std::move(dir)) {}
  std::filesystem::path dir_;
};

// Runs SQL (one or more statements) on the database of `uri`; throws
// std::runtime_error with the server's message when it fails. Returns the
// first column of the last statement's first row, "" when there is none.
std::string pg_sql(const std::string& uri, const std::string& statement);

// The build's shared cluster folder (the ctest fixture's).
std::filesystem::path shared_pg_cluster_dir();

// For a test of the PostgreSQL backend: a fresh schema in the process'
// cluster (the shared one, or one started on first use and stopped at the
// end of the test program), as a historian location. Throws, so the test
// fails with the message, when PostgreSQL is not installed.
// AMBDIAG_NO_POSTGRES=1 in the environment: nullopt (the caller skips the
// test, saying so).
std::optional<std::string> postgres_test_location();
// The process' cluster (started or attached on first use); nullptr like
// postgres_test_location.
const PgCluster* postgres_test_cluster();
// AMBDIAG_NO_POSTGRES=1: the PostgreSQL half of the tests is left out.
bool postgres_tests_disabled();

}  // namespace ambdiag::testing
