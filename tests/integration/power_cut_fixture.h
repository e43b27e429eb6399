// The power-cut test with real processes (docs/streaming.md, "Durable
// acknowledgement"): `ambdiag serve` runs on the power-cut VFS
// (ambdiag/storage/power_cut.h) and cuts itself at a chosen write, dropping
// everything its files had not fsynced, while several `ambdiag-agent`s
// stream; this process reads every ack the server sends (a reader on
// ambdiag_Ack in the test's partition) and notes the blocks acknowledged
// durable. After the cut: the file passes integrity_check and holds every
// one of them; a restarted server (without the VFS) gets the rest from the
// agents, which complete, every run stored once and sample for sample.
// The same during an analysis job: the cut comes at the job's next write
// after SIGUSR2; after the restart every job is done once.
#pragma once

#include <signal.h>

#include <random>
#include <map>
#include <set>
#include <tuple>

#include "ambdiag/proto/stream.h"
#include "ambdiag/storage/power_cut.h"
#include "fleet_fixture.h"
#include "sql_peek.h"

namespace ambdiag::testing {

// What the cuts showed (the figures).
struct CutTally {
  int tried = 0, cut = 0;        // cut points tried; those the server reached
  int64_t blocks_durable = 0;    // blocks acknowledged durable before a cut
  int64_t blocks_lost = 0;       // of those, missing after the cut (must be 0)
  int64_t committed_lost = 0;    // acknowledged only as committed and missing after the cut: what the cut did take
  int64_t runs_duplicated = 0;   // run rows beyond one per run id, chunks beyond the run's blocks (must be 0)
  int64_t jobs_duplicated = 0;   // jobs beyond one per key, results beyond one per job (must be 0)
  // Prints the figures and checks what every case must show: enough of the
  // cut points reached, nothing acknowledged durable lost, nothing twice.
  void expect_nothing_lost_or_twice(const char* what, int min_cut) const {
    print(what);
    EXPECT_GE(cut, min_cut) << what;  // a cut point may lie past the end
    EXPECT_EQ(blocks_lost, 0) << what;
    EXPECT_EQ(runs_duplicated, 0) << what;
    EXPECT_EQ(jobs_duplicated, 0) << what;
  }
  void print(const char* what) const {
    std::printf("%s: %d cut points tried, %d reached, %lld blocks acknowledged durable before a cut, %lld lost "
                "(%lld acknowledged only as committed were lost), %lld runs duplicated, %lld jobs duplicated\n",
                what, tried, cut, static_cast<long long>(blocks_durable), static_cast<long long>(blocks_lost),
                static_cast<long long>(committed_lost),
                static_cast<long long>(runs_duplicated), static_cast<long long>(jobs_duplicated));
  }
};

class PowerCutTest : public FleetTest {
 protected:
  // Block acks seen, (run_id, seq): durable ones, and committed-only ones.
  std::set<std::pair<std::string, int64_t>> durable, committed;
  std::optional<stream::AgentEndpoints> ack_reader;

  void SetUp() override {
    FleetTest::SetUp();
    setenv("CYCLONEDDS_URI", env["CYCLONEDDS_URI"].c_str(), 1);
    ack_reader.emplace(domain, partition);
  }

  std::string run_prefix;  // the runs of the current cut point: acks of others are old news

  void take_acks() {
    ack_reader->ack.take(4096, [&](const ambdiag_stream_Ack& a, const dds_sample_info_t&) {
      if (a.state != ambdiag_stream_ACK_STORED) return;
      if (std::string(a.run_id).rfind(run_prefix, 0) != 0) return;
      for (int64_t s = a.first_seq; s <= a.last_seq; ++s) (a.durable ? durable : committed).insert({a.run_id, s});
    });
  }

  // `ambdiag serve` on `db` cutting itself as `cut` says ("" for none).
  // With `seed` > 0 a random half of the unsynced writes survives.
  std::unique_ptr<Process> server_with_cut(const std::string& cut, uint64_t seed, std::vector<std::string> extra = {}) {
    if (!cut.empty()) env["AMBDIAG_POWER_CUT"] = cut;
    if (seed > 0) env["AMBDIAG_POWER_CUT_SEED"] = std::to_string(seed);
    extra.insert(extra.end(), {"--durable-within", "0.1", "--workers", "0"});
    auto p = start_server(extra);
    env.erase("AMBDIAG_POWER_CUT");
    env.erase("AMBDIAG_POWER_CUT_SEED");
    return p;
  }

  // Paced at the recording's rate, as a live pump streams: commits and
  // durable acks go on during the whole run, so cut points fall between them.
  std::unique_ptr<Process> replay_agent(const fs::path& run_dir, const fs::path& spool) {
    return std::make_unique<Process>(
        std::vector<std::string>{AMBDIAG_AGENT, "replay", run_dir.string(), "--timeout", "90", "--domain",
                                 std::to_string(domain), "--partition", partition, "--spool-dir", spool.string()},
        env, (dir / ("agent" + std::to_string(log_n++) + ".log")).string());
  }

  // Checks the file right after a cut: consistent, every durable ack's block there.
  void check_after_cut(CutTally& t) {
    EXPECT_EQ(sql_text(db, "PRAGMA integrity_check"), "ok");
    const auto held = [&](const std::string& run_id, int64_t seq) {
      return sql_int(db, "SELECT count(*) FROM sample_chunks WHERE run_id = " + sql_quote(run_id) +
                             " AND seq = " + std::to_string(seq)) == 1;
    };
    for (const auto& [run_id, seq] : committed)
      if (!durable.count({run_id, seq}) && !held(run_id, seq)) ++t.committed_lost;
    for (const auto& [run_id, seq] : durable) {
      ++t.blocks_durable;
      if (!held(run_id, seq)) {
        ++t.blocks_lost;
        ADD_FAILURE() << "block " << seq << " of run " << run_id << " was acknowledged durable and is lost";
      }
    }
  }

  // The writes an uncut streaming of `runs` makes: where cut points may fall.
  uint64_t baseline_writes(const std::vector<fs::path>& runs, int point) {
    use_folder(point);
    server = server_with_cut("track", 0);
    std::vector<std::unique_ptr<Process>> agents;
    for (size_t i = 0; i < runs.size(); ++i) agents.push_back(replay_agent(runs[i], dir / ("spool-b-" + std::to_string(i))));
    for (auto& a : agents) EXPECT_EQ(a->wait(120s), 0) << a->log() << "\n--- server ---\n" << server->log();
    server->signal(SIGTERM);
    EXPECT_EQ(server->wait(20s), 0) << server->log();
    const std::string log = server->log();
    const auto at = log.find("power-cut VFS saw ");
    if (at == std::string::npos) {
      ADD_FAILURE() << log;
      return 1;
    }
    return std::stoull(log.substr(at + 18));
  }

  void use_folder(int point) {
    const fs::path sub = dir / ("point-" + std::to_string(point));
    fs::create_directories(sub);
    db = sub / "historian.db";
    run_prefix = "CUT-" + std::to_string(point) + "/";
    durable.clear();
    committed.clear();
  }

  // One cut point: fresh file and spools; agents stream `runs`; the server
  // cuts itself at write `at` (a random half of the unsynced writes kept
  // with `seed`); then it restarts and the agents finish.
  void stream_and_cut(const std::vector<fs::path>& runs, int point, uint64_t at, uint64_t seed, CutTally& t) {
    use_folder(point);
    ++t.tried;
    server = server_with_cut("writes:" + std::to_string(at), seed);
    std::vector<std::unique_ptr<Process>> agents;
    for (size_t i = 0; i < runs.size(); ++i)
      agents.push_back(replay_agent(runs[i], dir / ("spool-" + std::to_string(point) + "-" + std::to_string(i))));
    const auto deadline = std::chrono::steady_clock::now() + 120s;
    auto all_done = [&] {
      for (auto& a : agents)
        if (a->running()) return false;
      return true;
    };
    while (server->running() && !all_done() && std::chrono::steady_clock::now() < deadline) {
      take_acks();
      std::this_thread::sleep_for(5ms);
    }
    const bool was_cut = server->wait(all_done() ? 1s : 30s) == storage::power_cut::kExitCode;
    std::this_thread::sleep_for(200ms);  // acks still on the way from the dead server
    take_acks();
    if (was_cut) {
      ++t.cut;
      check_after_cut(t);
      server = start_server({"--workers", "0"});
    }
    for (auto& a : agents) EXPECT_EQ(a->wait(120s), 0) << a->log() << "\n--- server ---\n" << server->log();
    // Every run complete, once, sample for sample.
    for (const auto& r : runs) {
      const RunRecording rec = expect_stored_complete(r);
      const int64_t blocks = (rec.frame_count() + 511) / 512;
      t.runs_duplicated += std::max<int64_t>(0, sql_int(db, "SELECT count(*) FROM sample_chunks WHERE run_id = " +
                                                                 sql_quote(rec.run_id)) - blocks);
    }
    t.runs_duplicated += sql_int(db, "SELECT count(*) FROM runs") - static_cast<int64_t>(runs.size());
    server->signal(SIGTERM);
    EXPECT_EQ(server->wait(20s), 0) << server->log();
  }

  // Several agents' runs of `seconds` each; run ids of their own per cut
  // point, so that acks of an earlier point's server never count for this one.
  std::vector<fs::path> fleet_runs(int n, double seconds, const std::string& tag) {
    std::vector<fs::path> runs;
    for (int i = 0; i < n; ++i) runs.push_back(short_run(seconds, "CUT-" + tag + "/" + std::to_string(i)));
    return runs;
  }

  // Cut points at random writes of the streaming of `agents` runs of
  // `seconds` (seeded); every other one keeps a random half of the unsynced
  // writes.
  CutTally cut_streaming(int agents, double seconds, int points, unsigned seed) {
    const uint64_t writes = baseline_writes(fleet_runs(agents, seconds, "0"), 0);
    std::mt19937_64 rng(seed);
    CutTally t;
    for (int i = 1; i <= points; ++i) {
      const uint64_t at = 1 + rng() % writes;
      const uint64_t keep_seed = i % 2 == 0 ? 1 + rng() % 1000000 : 0;
      stream_and_cut(fleet_runs(agents, seconds, std::to_string(i)), i, at, keep_seed, t);
      if (::testing::Test::HasFatalFailure()) break;
    }
    return t;
  }

  // A cut during an analysis job: a pump with a model streams identification
  // runs (`ambdiag-agent simulate`), each analysed by a job; once a job is
  // running, after a random delay, SIGUSR2 makes the server cut at its next
  // write. After the restart: every run complete, every job done once.
  void cut_during_job(int point, std::mt19937_64& rng, CutTally& t) {
    use_folder(point);
    ++t.tried;
    tokens.clear();  // a new file: new tokens
    const std::string pump = "PC-" + std::to_string(point);
    run_prefix = pump + "/";
    env["AMBDIAG_POWER_CUT"] = "signal";
    start_service({"--workers", "1", "--durable-within", "0.1"});
    env.erase("AMBDIAG_POWER_CUT");
    const auto m = put("/api/v1/pumps/" + pump + "/model", read_file_bytes(reference_model.string()));
    ASSERT_EQ(m->status, 200) << m->body;
    auto agent = simulate({pump, reference_model, 2, 0, 0, point, {}, 0}, 0.1);
    bool running = false;
    for (auto deadline = std::chrono::steady_clock::now() + 180s; !running && std::chrono::steady_clock::now() < deadline;) {
      const auto r = get("/api/v1/jobs?pump_id=" + pump + "&status=running");
      running = r && r->status == 200 && !json_of(r)["jobs"].empty();
      take_acks();
      if (!running) std::this_thread::sleep_for(20ms);
    }
    ASSERT_TRUE(running) << server->log();
    std::this_thread::sleep_for(std::chrono::milliseconds(rng() % 500));
    take_acks();
    ::kill(server->pid(), SIGUSR2);
    const int code = server->wait(60s);
    std::this_thread::sleep_for(200ms);
    take_acks();
    if (code == storage::power_cut::kExitCode) {
      ++t.cut;
      check_after_cut(t);
    } else {
      ADD_FAILURE() << "the server did not cut (exit " << code << ")\n" << server->log();
    }
    start_service({"--workers", "1"});
    EXPECT_EQ(agent->wait(300s), 0) << agent->log() << "\n--- server ---\n" << server->log();
    const auto runs = json_of(get("/api/v1/pumps/" + pump + "/runs"))["runs"];
    EXPECT_EQ(runs.size(), 2u) << runs.dump();
    for (const auto& r : runs) {
      EXPECT_EQ(r["status"], "complete") << r.dump();
      EXPECT_EQ(wait_analysis(r["run_id"], 300s).value("status", ""), "done");
    }
    // One job per key, each done with its result; the attempts show the cut.
    std::map<std::tuple<std::string, std::string, int, int>, int> per_key;
    for (const auto& j : json_of(get("/api/v1/jobs?pump_id=" + pump))["jobs"]) {
      const auto key = std::make_tuple(j.value("kind", ""), j.value("run_id", ""), j.value("model_version", 0),
                                       j.value("reference_version", 0));
      t.jobs_duplicated += per_key[key]++ > 0 ? 1 : 0;
      EXPECT_EQ(j.value("status", ""), "done") << j.dump();
    }
    t.runs_duplicated += sql_int(db, "SELECT count(*) FROM runs") - 2;
    server->signal(SIGTERM);
    EXPECT_EQ(server->wait(30s), 0) << server->log();
  }

  // `points` cuts during analysis jobs, each after a random delay (seeded).
  CutTally cut_jobs(int points, unsigned seed) {
    std::mt19937_64 rng(seed);
    CutTally t;
    for (int point = 1; point <= points && !::testing::Test::HasFatalFailure(); ++point) cut_during_job(point, rng, t);
    return t;
  }
};

}  // namespace ambdiag::testing
