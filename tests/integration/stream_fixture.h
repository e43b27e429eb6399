// Shared set-up of the streaming integration tests: a scratch folder, a DDS
// domain of the test's own (other engineers' tests run on this machine at
// the same time), the loopback Cyclone config, and helpers that start the
// real `ambdiag serve` and `ambdiag-agent` processes.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "ambdiag/core/io_util.h"
#include "ambdiag/core/run_recording.h"
#include "ambdiag/storage/historian.h"
#include "process.h"
#include "test_support.h"

namespace ambdiag::testing {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// A domain id per test process: pid-derived, away from the default 0. Two
// processes can still draw the same one (120 ids), so each test also has
// a partition of its own: servers, agents and readers of other tests (other
// worktrees run theirs on this machine) never match it.
inline int unique_domain() { return 100 + static_cast<int>(getpid() % 120); }
inline std::string unique_partition() {
  static int n = 0;
  return "test-" + std::to_string(getpid()) + "-" + std::to_string(n++) + "-" +
         std::to_string(std::chrono::steady_clock::now().time_since_epoch().count() % 1000000007);
}

class StreamTest : public ::testing::Test {
 protected:
  fs::path dir = scratch_dir();
  int domain = unique_domain();
  std::string partition = unique_partition();
  fs::path db = dir / "historian.db";
  std::map<std::string, std::string> env{{"CYCLONEDDS_URI", "file://" AMBDIAG_CYCLONE_LOCAL_XML}};
  int log_n = 0;

  std::unique_ptr<Process> start_server(const std::vector<std::string>& extra = {}) {
    // Open reads: these tests read runs back over REST without tokens.
    std::vector<std::string> argv = {AMBDIAG_CLI, "serve", "--db", db.string(), "--http-port", "0", "--domain",
                                     std::to_string(domain), "--partition", partition, "--anonymous-read"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return std::make_unique<Process>(argv, env, (dir / ("server" + std::to_string(log_n++) + ".log")).string());
  }
  // One agent per spool folder: agents running together need one each.
  std::unique_ptr<Process> start_agent(const fs::path& run_dir, const std::vector<std::string>& extra = {},
                                       const fs::path& spool = {}) {
    std::vector<std::string> argv = {AMBDIAG_AGENT, "replay", run_dir.string(), "--domain", std::to_string(domain),
                                     "--partition", partition, "--spool-dir",
                                     (spool.empty() ? dir / "spool" : spool).string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return std::make_unique<Process>(argv, env, (dir / ("agent" + std::to_string(log_n++) + ".log")).string());
  }
  // The REST port a server printed on stderr ("REST on port N"), 0 if not yet.
  static int rest_port(Process& server, std::chrono::milliseconds timeout = 10s) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      const std::string log = server.log();
      if (const auto at = log.find("REST on port "); at != std::string::npos) return std::stoi(log.substr(at + 13));
      std::this_thread::sleep_for(50ms);
    }
    return 0;
  }
  // The run as the historian holds it (a reader beside the running server).
  std::optional<storage::RunInfo> find_run(const std::string& run_id) {
    if (!storage::is_postgres_location(db.string()) && !fs::exists(db)) return std::nullopt;
    auto h = storage::Historian::open(db.string(), storage::Historian::Mode::read);
    return h.find_run(run_id);
  }
  std::string stored_samples(const std::string& run_id) {
    auto h = storage::Historian::open(db.string(), storage::Historian::Mode::read);
    return h.read_samples(run_id);
  }
  // The recording in `run_dir` is held complete, sample for sample; returns
  // it (with its run id) for further checks.
  RunRecording expect_stored_complete(const fs::path& run_dir) {
    RunRecording rec = read_run(run_dir.string());
    const auto info = find_run(rec.run_id);
    EXPECT_TRUE(info) << rec.run_id;
    if (!info) return rec;
    EXPECT_EQ(info->status, storage::RunStatus::complete) << rec.run_id << ": " << info->status_reason;
    EXPECT_TRUE(stored_samples(rec.run_id) == read_file_bytes((run_dir / "samples.f32").string())) << rec.run_id;
    return rec;
  }
  // Waits until the run has `status` (or the deadline passes).
  bool wait_status(const std::string& run_id, storage::RunStatus status, std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      try {
        if (auto r = find_run(run_id); r && r->status == status) return true;
      } catch (const std::exception&) {
        // the server may be creating the file right now
      }
      std::this_thread::sleep_for(100ms);
    }
    return false;
  }
  // The first `seconds` of the reference run under a new run id (and pump,
  // when given), written to the scratch folder (paced replays of it take
  // `seconds`).
  fs::path short_run(double seconds, const std::string& run_id, const std::string& pump_id = "") {
    RunRecording run = read_run(data_file("reference_pump/run_ref_1").string());
    if (!pump_id.empty()) run.pump_id = pump_id;
    const auto frames = static_cast<size_t>(seconds * run.sample_rate_hz);
    run.samples.resize(frames * run.channels.size());
    run.run_id = run_id;
    run.kind = "monitoring";
    run.excitation.reset();
    const fs::path out = dir / ("run_" + std::to_string(log_n++));
    write_run(out.string(), run);
    return out;
  }
};

}  // namespace ambdiag::testing
