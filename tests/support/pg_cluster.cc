#include "pg_cluster.h"

#include <gtest/gtest.h>
#include <libpq-fe.h>
#include <pwd.h>
#include <sys/wait.h>
#include <csignal>
#include <cerrno>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace ambdiag::testing {

namespace fs = std::filesystem;

namespace {

// Unix socket only: the port is just the socket's name in our folder.
constexpr int kPort = 5432;

// The newest PostgreSQL's programs: Debian's /usr/lib/postgresql/N/bin, else PATH.
fs::path bin_dir() {
  std::vector<std::pair<int, fs::path>> found;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator("/usr/lib/postgresql", ec)) {
    const auto bin = e.path() / "bin";
    if (fs::exists(bin / "initdb") && fs::exists(bin / "pg_ctl"))
      found.emplace_back(std::atoi(e.path().filename().c_str()), bin);
  }
  if (!found.empty()) return std::max_element(found.begin(), found.end())->second;
  if (const char* path = std::getenv("PATH")) {
    std::stringstream ss(path);
    for (std::string d; std::getline(ss, d, ':');)
      if (fs::exists(fs::path(d) / "initdb") && fs::exists(fs::path(d) / "pg_ctl")) return d;
  }
  throw std::runtime_error(
      "PostgreSQL is not installed (no initdb/pg_ctl in /usr/lib/postgresql/*/bin or PATH): the PostgreSQL half of "
      "the tests needs it; run deploy/install-deps.sh (Debian package postgresql), or set AMBDIAG_NO_POSTGRES=1 to "
      "leave those tests out");
}

// PostgreSQL refuses to run as root: as root, run its programs as `postgres`.
const passwd* server_user() {
  if (geteuid() != 0) return nullptr;
  const passwd* pw = getpwnam("postgres");
  if (!pw) throw std::runtime_error("running as root, but there is no `postgres` user to run PostgreSQL as (install the postgresql package)");
  return pw;
}

// Runs a program (as the server's user), its output appended to `log`;
// returns the exit status.
int run(const std::vector<std::string>& argv, const fs::path& log) {
  const passwd* pw = server_user();
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    if (pw && (setgid(pw->pw_gid) != 0 || setuid(pw->pw_uid) != 0)) _exit(126);
    if (FILE* f = std::fopen(log.c_str(), "a")) {
      dup2(fileno(f), 1);
      dup2(fileno(f), 2);
    }
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execv(args[0], args.data());
    _exit(127);
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string uri_of(const fs::path& dir) {
  return "postgresql:///postgres?host=" + dir.string() + "&port=" + std::to_string(kPort) + "&user=postgres";
}

struct ConnFree {
  void operator()(PGconn* c) const { PQfinish(c); }
};

// An empty folder owned by the server's user (whatever an interrupted run
// left there is stopped and removed).
void make_server_dir(const fs::path& dir) {
  PgCluster::stop(dir);
  fs::create_directories(dir);
  fs::permissions(dir, fs::perms::owner_all);
  if (const passwd* pw = server_user(); pw && chown(dir.c_str(), pw->pw_uid, pw->pw_gid) != 0)
    throw std::runtime_error("chown " + dir.string() + " failed");
}

// `pg_ctl -D DIR/data ARGS...` (as the server's user), its output in
// DIR/log; throws with that log when it fails.
void pg_ctl(const fs::path& dir, const std::vector<std::string>& args, const std::string& what) {
  std::vector<std::string> argv = {(bin_dir() / "pg_ctl").string(), "-D", (dir / "data").string()};
  argv.insert(argv.end(), args.begin(), args.end());
  if (run(argv, dir / "log") != 0)
    throw std::runtime_error("pg_ctl " + what + " in " + dir.string() + " failed:\n" + read_text(dir / "log"));
}

// pg_ctl stop -m immediate: the server stops at once; whether it ran or not.
void stop_now(const fs::path& dir, const fs::path& log) {
  run({(bin_dir() / "pg_ctl").string(), "-D", (dir / "data").string(), "-m", "immediate", "-w", "stop"}, log);
}

// pg_ctl start of the data folder in `dir`, on the folder's socket only.
// fsync off: a test cluster need not survive a power cut. Enough
// connections for a server's reader pool and the concurrency tests.
void start_server(const fs::path& dir, bool durable) {
  const std::string opts = "-c listen_addresses='' -c unix_socket_directories=" + dir.string() + " -p " +
                           std::to_string(kPort) + " -c max_connections=300" +
                           (durable ? "" : " -c fsync=off -c full_page_writes=off");
  pg_ctl(dir, {"-l", (dir / "log").string(), "-w", "-t", "60", "-o", opts, "start"}, "start");
  std::ofstream(dir / "uri") << uri_of(dir);
}

}  // namespace

PgCluster PgCluster::start(const fs::path& dir, bool durable) {
  make_server_dir(dir);
  const fs::path log = dir / "log";
  if (run({(bin_dir() / "initdb").string(), "-D", (dir / "data").string(), "--auth=trust", "--username=postgres",
           "--encoding=UTF8", "--locale=C.UTF-8", "--no-sync"},
          log) != 0)
    throw std::runtime_error("initdb in " + dir.string() + " failed:\n" + read_text(log));
  start_server(dir, durable);
  return PgCluster(dir);
}

PgCluster PgCluster::start_standby(const fs::path& dir, const PgCluster& primary, const std::string& name) {
  make_server_dir(dir);
  pg_sql(primary.uri(), "SELECT pg_create_physical_replication_slot('" + name + "')");
  const fs::path log = dir / "log";
  const std::string source =
      "host=" + primary.dir().string() + " port=" + std::to_string(kPort) + " user=postgres application_name=" + name;
  if (run({(bin_dir() / "pg_basebackup").string(), "-d", source, "-D", (dir / "data").string(), "-R", "-X", "stream",
           "-S", name, "--no-sync"},
          log) != 0)
    throw std::runtime_error("pg_basebackup into " + dir.string() + " failed:\n" + read_text(log));
  start_server(dir, false);
  return PgCluster(dir);
}

void PgCluster::crash() const {
  std::ifstream in(dir_ / "data" / "postmaster.pid");  // its first line is the postmaster's PID
  int pid = 0;
  in >> pid;
  if (pid > 0) kill(pid, SIGKILL);
}

void PgCluster::shut_down() const { stop_now(dir_, dir_ / "log"); }

void PgCluster::start_again() const { start_server(dir_, false); }

void PgCluster::promote() const { pg_ctl(dir_, {"-w", "-t", "60", "promote"}, "promote"); }

std::optional<PgCluster> PgCluster::attach(const fs::path& dir) {
  if (!fs::exists(dir / "uri")) return std::nullopt;
  std::unique_ptr<PGconn, ConnFree> conn(PQconnectdb(uri_of(dir).c_str()));
  if (PQstatus(conn.get()) != CONNECTION_OK) return std::nullopt;
  return PgCluster(dir);
}

void PgCluster::stop(const fs::path& dir) {
  std::error_code ec;
  if (fs::exists(dir / "data" / "postmaster.pid", ec)) stop_now(dir, "/dev/null");
  fs::remove_all(dir, ec);
}

void PgCluster::restart(const fs::path& dir, const std::string& mode) {
  // pg_ctl restart starts with the options of the last start (postmaster.opts).
  pg_ctl(dir, {"-l", (dir / "log").string(), "-m", mode, "-w", "-t", "60", "restart"}, "restart -m " + mode);
}

std::string PgCluster::uri() const { return uri_of(dir_); }

std::string pg_sql(const std::string& uri, const std::string& statement) {
  std::unique_ptr<PGconn, ConnFree> conn(PQconnectdb(uri.c_str()));
  if (PQstatus(conn.get()) != CONNECTION_OK)
    throw std::runtime_error("cannot connect to the test cluster: " + std::string(PQerrorMessage(conn.get())));
  PQsetNoticeProcessor(conn.get(), [](void*, const char*) {}, nullptr);
  PGresult* r = PQexec(conn.get(), statement.c_str());
  const auto st = PQresultStatus(r);
  std::string out = st == PGRES_TUPLES_OK && PQntuples(r) > 0 ? PQgetvalue(r, 0, 0) : "";
  std::string err = PQresultErrorMessage(r);
  PQclear(r);
  if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK) throw std::runtime_error(statement + ": " + err);
  return out;
}

std::string PgCluster::fresh_schema_uri(const std::string& name) const {
  pg_sql(uri(), "CREATE SCHEMA \"" + name + "\"");
  return uri() + "&options=-csearch_path%3D" + name;
}

fs::path shared_pg_cluster_dir() { return AMBDIAG_TEST_PG_DIR; }

namespace {

// Clusters of test programs that died before stopping theirs
// (ambdiag-pg-PID of a PID that no longer runs).
void stop_orphans() {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(fs::temp_directory_path(), ec)) {
    const std::string name = e.path().filename().string();
    if (!name.starts_with("ambdiag-pg-") || name.find_first_not_of("0123456789", 11) != std::string::npos) continue;
    const long pid = std::atol(name.c_str() + 11);
    if (pid > 0 && kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) PgCluster::stop(e.path());
  }
}

// The process' cluster: the shared one if it runs, else one of its own,
// stopped by the gtest environment at the end of the program.
class ClusterEnvironment : public ::testing::Environment {
 public:
  const PgCluster& get() {
    std::lock_guard lock(mu_);
    if (!cluster_) {
      cluster_ = PgCluster::attach(shared_pg_cluster_dir());
      if (!cluster_) {
        stop_orphans();
        cluster_ = PgCluster::start(fs::temp_directory_path() / ("ambdiag-pg-" + std::to_string(getpid())));
        owned_ = true;
      }
    }
    return *cluster_;
  }
  void TearDown() override {
    std::lock_guard lock(mu_);
    if (cluster_ && owned_) PgCluster::stop(cluster_->dir());
    cluster_.reset();
  }

 private:
  std::mutex mu_;
  std::optional<PgCluster> cluster_;
  bool owned_ = false;
};

ClusterEnvironment& environment() {
  static ClusterEnvironment* env = [] {
    auto* e = new ClusterEnvironment;
    ::testing::AddGlobalTestEnvironment(e);  // gtest owns it; TearDown runs even when tests failed
    return e;
  }();
  return *env;
}

}  // namespace

bool postgres_tests_disabled() {
  const char* v = std::getenv("AMBDIAG_NO_POSTGRES");
  return v && std::string(v) == "1";
}

const PgCluster* postgres_test_cluster() {
  if (postgres_tests_disabled()) return nullptr;
  return &environment().get();
}

std::optional<std::string> postgres_test_location() {
  const PgCluster* c = postgres_test_cluster();
  if (!c) return std::nullopt;
  static std::atomic<int> counter{0};
  return c->fresh_schema_uri("t_" + std::to_string(getpid()) + "_" + std::to_string(++counter));
}

}  // namespace ambdiag::testing
