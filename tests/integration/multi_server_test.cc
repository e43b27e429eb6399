// Several servers on one SQLite file (multi_server_fixture.h), small: six
// runs, a 2 s lease. And `--parts` / `--instance` refused when wrong.
#include <sstream>

#include "multi_server_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(MultiServerTest, AKilledAndAPausedWorkerLoseTheirJobsAndEveryRunIsAnalysedOnce) {
  run_scenario({6, 2.0, 2});
}

// A bad part list, or an option of a part the process does not run, is a
// usage error (exit 2) naming it, before anything opens the file.
TEST_F(MultiServerTest, ABadPartsListOrAnOptionOfAPartNotRunIsAUsageError) {
  const auto serve = [&](std::vector<std::string> args) {
    args.insert(args.begin(), {AMBDIAG_CLI, "serve", "--db", db.string()});
    Process p(args, env, (dir / ("usage" + std::to_string(log_n++) + ".log")).string());
    return std::pair{p.wait(30s), p.log()};
  };
  for (const auto& [args, named] : std::vector<std::pair<std::vector<std::string>, std::string>>{
           {{"--parts", "ingest,rst", "--http-port", "0"}, "unknown part 'rst'"},
           {{"--parts", "", "--http-port", "0"}, "an empty part"},
           {{"--parts", "rest,,ingest", "--http-port", "0"}, "an empty part"},
           {{"--parts", "rest,rest", "--http-port", "0"}, "'rest' given twice"},
           {{"--parts", "analysis", "--http-port", "0"}, "--http-port: this process runs no rest"},
           {{"--parts", "ingest,rest", "--http-port", "0", "--workers", "2"}, "--workers: this process runs no analysis"},
           {{"--parts", "rest"}, "missing --http-port"},
           {{"--instance", "a b", "--http-port", "0"}, "--instance"},
           {{"--job-lease", "0.1", "--http-port", "0"}, "--job-lease"}}) {
    const auto [rc, log] = serve(args);
    EXPECT_EQ(rc, 2) << log;
    EXPECT_NE(log.find(named), std::string::npos) << log;
  }
  EXPECT_FALSE(fs::exists(db)) << "nothing was opened";
}

// Analysis alone opens no port and no DDS reader; a second ingest on the
// file stands by for the group the first holds (docs/streaming.md), beside
// analysis and rest processes.
TEST_F(MultiServerTest, AnAnalysisOnlyProcessListensNowhereAndASecondIngestStandsBy) {
  make_tokens();
  start_part("A", "ingest,rest");
  auto& analysis = start_part("W", "analysis", {"--workers", "1"});
  start_part("R", "rest");
  std::this_thread::sleep_for(500ms);
  EXPECT_TRUE(analysis.process->running()) << analysis.process->log();
  EXPECT_EQ(analysis.process->log().find("REST on port"), std::string::npos) << analysis.process->log();
  EXPECT_EQ(analysis.process->log().find("DDS domain"), std::string::npos) << analysis.process->log();
  // No listening socket of its own: every socket inode it holds is absent
  // from the listening TCP sockets of the host.
  std::set<std::string> inodes;
  for (const auto& fd : fs::directory_iterator("/proc/" + std::to_string(analysis.process->pid()) + "/fd")) {
    std::error_code ec;
    const auto target = fs::read_symlink(fd.path(), ec).string();
    if (target.rfind("socket:[", 0) == 0) inodes.insert(target.substr(8, target.size() - 9));
  }
  for (const char* table : {"/proc/net/tcp", "/proc/net/tcp6"}) {
    std::istringstream lines(read_file_bytes(table));
    std::string line;
    std::getline(lines, line);  // header
    while (std::getline(lines, line)) {
      std::istringstream f(line);
      std::string sl, local, remote, st, queues, timer, retr, uid, timeout, inode;
      f >> sl >> local >> remote >> st >> queues >> timer >> retr >> uid >> timeout >> inode;
      if (st == "0A") {  // LISTEN
        EXPECT_FALSE(inodes.count(inode)) << "listens on " << local;
      }
    }
  }
  const auto health_r = json_on("R", "/api/v1/health");
  EXPECT_EQ(health_r["parts"], nlohmann::json::array({"rest"}));
  EXPECT_EQ(health_r["ingest_groups"], nlohmann::json::array());
  start_part("A2", "ingest,rest");
  EXPECT_EQ(json_on("A", "/api/v1/health")["ingest_groups"].at(0)["role"], "holder");
  EXPECT_EQ(json_on("A2", "/api/v1/health")["ingest_groups"].at(0)["role"], "standby");
  EXPECT_TRUE(analysis.process->running());
}

}  // namespace
}  // namespace ambdiag::testing
