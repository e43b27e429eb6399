// Several `ambdiag serve` processes on one SQLite file in one ingest group
// (docs/streaming.md "Several servers: ingest groups and failover"): paced
// agents stream while the holder is killed (-9) or paused (SIGSTOP) past
// its lease. What the standby's health shows, and when (measured from the
// fault), and what the historian holds afterwards: every run complete once,
// sample for sample, no chunk beyond its blocks.
#pragma once

#include <httplib.h>
#include <signal.h>

#include <algorithm>
#include <cstdio>
#include <vector>

#include <nlohmann/json.hpp>

#include "server_health.h"
#include "sql_peek.h"
#include "stream_fixture.h"

namespace ambdiag::testing {

// Seconds from the fault (kill -9 or SIGSTOP of the holder): -1 if never.
struct FailoverFigures {
  double taken_over_s = -1;     // the standby's health says holder
  double first_block_s = -1;    // the standby's first commit holding a block (new or already stored)
  double runs_complete_s = -1;  // the last of the runs complete in the historian
  double agents_done_s = -1;    // the last agent ended, its run's verdict received (sent once durable)
  void print(const std::string& what) const {
    std::printf("%s: taken over after %.2f s, first block committed by the new holder after %.2f s, every run "
                "complete after %.2f s, every agent's verdict after %.2f s\n",
                what.c_str(), taken_over_s, first_block_s, runs_complete_s, agents_done_s);
    std::fflush(stdout);
  }
};

class FailoverTest : public StreamTest {
 protected:
  using Clock = std::chrono::steady_clock;

  struct Member {
    std::string name;
    std::unique_ptr<Process> process;
    int port = 0;
  };

  // A server of the group: ingest and REST only (--workers 0: analysis is
  // not yet shared between servers), lease `lease_s`.
  Member start_member(const std::string& name, double lease_s, std::vector<std::string> extra = {}) {
    char lease[32];
    std::snprintf(lease, sizeof lease, "%g", lease_s);
    extra.insert(extra.end(), {"--workers", "0", "--instance", name, "--ingest-lease", lease});
    Member m{name, start_server(extra), 0};
    m.port = rest_port(*m.process);
    EXPECT_GT(m.port, 0) << m.process->log();
    return m;
  }

  static nlohmann::json health(const Member& m) { return health_on_port(m.port); }
  static nlohmann::json group_of(const Member& m) { return ingest_group_on_port(m.port); }
  static std::string role(const Member& m) { return group_of(m).value("role", ""); }
  static bool wait_role(const Member& m, const std::string& want, std::chrono::milliseconds timeout) {
    for (const auto deadline = Clock::now() + timeout; Clock::now() < deadline; std::this_thread::sleep_for(20ms))
      if (role(m) == want) return true;
    return false;
  }
  static double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

  // `n` runs of `seconds`, each of a pump of its own, ids TAG/i.
  std::vector<fs::path> fleet_runs(int n, double seconds, const std::string& tag) {
    std::vector<fs::path> runs;
    for (int i = 0; i < n; ++i) runs.push_back(short_run(seconds, tag + "/" + std::to_string(i), tag + "-P" + std::to_string(i)));
    return runs;
  }
  // Paced at the recording's rate, as live pumps stream; a spool each.
  std::vector<std::unique_ptr<Process>> start_agents(const std::vector<fs::path>& runs) {
    std::vector<std::unique_ptr<Process>> agents;
    for (const auto& r : runs)
      agents.push_back(start_agent(r, {"--timeout", "90"}, dir / ("spool-" + r.filename().string())));
    return agents;
  }
  static std::string run_id_of(const fs::path& run) { return read_run(run.string()).run_id; }

  // Every run has at least `chunks` chunks stored: all begun under the holder.
  bool wait_chunks(const std::vector<fs::path>& runs, int64_t chunks, std::chrono::milliseconds timeout) {
    for (const auto deadline = Clock::now() + timeout; Clock::now() < deadline; std::this_thread::sleep_for(50ms)) {
      bool all = true;
      for (const auto& r : runs) {
        const auto info = find_run(run_id_of(r));
        all = all && info && info->received_chunks >= chunks;
      }
      if (all) return true;
    }
    return false;
  }
  bool all_complete(const std::vector<fs::path>& runs) {
    for (const auto& r : runs) {
      const auto info = find_run(run_id_of(r));
      if (!info || info->status != storage::RunStatus::complete) return false;
    }
    return true;
  }

  // After a fault hit the holder at `t0`: when `standby` says holder, when
  // it committed its first block, when every run is complete, when every
  // agent has ended (polled every 20 ms; runs every 100 ms).
  FailoverFigures measure(const Member& standby, const std::vector<fs::path>& runs,
                          std::vector<std::unique_ptr<Process>>& agents, Clock::time_point t0,
                          std::chrono::milliseconds timeout) {
    FailoverFigures f;
    auto next_db_look = Clock::now();
    // Blocks it committed while it held the group before (the slow test
    // alternates the holder): it cannot commit again before it takes over.
    std::optional<int64_t> blocks_before;
    while (since(t0) < std::chrono::duration<double>(timeout).count() && (f.runs_complete_s < 0 || f.agents_done_s < 0)) {
      const auto h = health(standby);
      if (h.contains("ingest_groups")) {
        if (f.taken_over_s < 0 && h["ingest_groups"][0].value("role", "") == "holder") f.taken_over_s = since(t0);
        const auto& in = h["ingest"];
        const int64_t blocks = in.value("blocks_stored", int64_t{0}) + in.value("blocks_duplicate", int64_t{0});
        if (!blocks_before) blocks_before = blocks;
        if (f.first_block_s < 0 && blocks > *blocks_before) f.first_block_s = since(t0);
      }
      if (f.agents_done_s < 0 && std::none_of(agents.begin(), agents.end(), [](auto& a) { return a->running(); }))
        f.agents_done_s = since(t0);
      if (f.runs_complete_s < 0 && Clock::now() >= next_db_look) {
        next_db_look = Clock::now() + 100ms;
        if (all_complete(runs)) f.runs_complete_s = since(t0);
      }
      std::this_thread::sleep_for(20ms);
    }
    return f;
  }

  // Every agent verified complete; every run complete in the historian,
  // sample for sample, one row, and exactly its blocks as chunks.
  void expect_complete_once(std::vector<std::unique_ptr<Process>>& agents, const std::vector<fs::path>& runs,
                            const std::string& servers_log) {
    for (auto& a : agents) EXPECT_EQ(a->wait(120s), 0) << a->log() << "\n--- servers ---\n" << servers_log;
    for (const auto& r : runs) {
      const RunRecording rec = expect_stored_complete(r);
      const int64_t blocks = (rec.frame_count() + 511) / 512;
      EXPECT_EQ(sql_int(db, "SELECT count(*) FROM sample_chunks WHERE run_id = " + sql_quote(rec.run_id)), blocks)
          << rec.run_id;
      EXPECT_EQ(sql_int(db, "SELECT count(*) FROM runs WHERE run_id = " + sql_quote(rec.run_id)), 1) << rec.run_id;
    }
  }

  // Pauses `holder` until `standby` holds the group. A pause that lands
  // inside the holder's SQLite write transaction blocks every writer (the
  // standby's takeover too) until it resumes: then it is resumed and paused
  // again, up to three times. Returns when the pause began, or nothing.
  std::optional<Clock::time_point> pause_until_taken_over(Member& holder, const Member& standby, double lease_s) {
    const auto wait = std::chrono::milliseconds(static_cast<long>(1000 * (3 * lease_s + 2)));
    for (int attempt = 0; attempt < 3; ++attempt) {
      holder.process->signal(SIGSTOP);
      const auto t0 = Clock::now();
      if (wait_role(standby, "holder", wait)) return t0;
      std::printf("the pause of %s held the database's write lock: resumed, paused again\n", holder.name.c_str());
      holder.process->signal(SIGCONT);
      std::this_thread::sleep_for(1s);
    }
    return std::nullopt;
  }

  static std::string logs(const std::vector<const Member*>& members) {
    std::string out;
    for (const auto* m : members) out += "--- " + m->name + " ---\n" + m->process->log();
    return out;
  }
};

}  // namespace ambdiag::testing
