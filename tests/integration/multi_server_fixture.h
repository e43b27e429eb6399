// Several `ambdiag serve` processes on ONE SQLite file or PostgreSQL database (issue 22,
// docs/service.md "Several servers"): A runs ingest and REST, B and C run
// the analysis and REST. Agents stream identification runs into A, whose
// ingest queues each run's analysis in the commit that completes it; B and
// C take the jobs with a short lease. B is killed (kill -9) while it runs a
// job: the job is queued again once its lease expires and another worker
// takes it (the time is measured and printed); B comes back as B2. C is paused (SIGSTOP)
// while it runs a job, past its lease: B2 takes the job and stores its
// result; C resumes (SIGCONT) and its late result is refused. Then: every
// run analysed exactly once (one job per run, done, one trend point per
// run, one job.done event per job), an event stream on A saw the analyses
// B, B2 and C did, a client resuming on C with A's Last-Event-ID gets the
// same events with the same ids, and A, C and B2 answer the same for the
// pump. multi_server_test.cc runs it small (fast suite), the slow test
// with more runs and a longer lease.
#pragma once

#include <signal.h>
#include <sqlite3.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <set>

#include "event_stream.h"
#include "pg_cluster.h"
#include "service_fixture.h"

namespace ambdiag::testing {

struct MultiServerScenario {
  int runs = 4;
  double lease_s = 2;
  int c_workers = 2;
};

class MultiServerTest : public ServiceTest {
 protected:
  struct Server {
    std::unique_ptr<Process> process;
    int port = 0;
  };
  std::map<std::string, Server> servers;
  static constexpr const char* kPump = "P-101";

  void make_tokens() {
    for (const char* role : {"viewer", "operator", "engineer", "admin"})
      if (!tokens.count(role)) tokens[role] = add_token(role, role);
  }

  // `ambdiag serve --parts PARTS --instance NAME` on the shared file.
  Server& start_part(const std::string& name, const std::string& parts, const std::vector<std::string>& extra = {}) {
    std::vector<std::string> argv = {AMBDIAG_CLI, "serve", "--db", db.string(), "--parts", parts, "--instance", name,
                                     "--rate-limit", "0"};
    if (parts.find("ingest") != std::string::npos)
      argv.insert(argv.end(), {"--domain", std::to_string(domain), "--partition", partition});
    if (parts.find("rest") != std::string::npos) argv.insert(argv.end(), {"--http-port", "0"});
    argv.insert(argv.end(), extra.begin(), extra.end());
    Server& s = servers[name];
    s.process = std::make_unique<Process>(argv, env, (dir / ("server-" + name + ".log")).string());
    if (parts.find("rest") != std::string::npos) {
      s.port = rest_port(*s.process);
      EXPECT_GT(s.port, 0) << s.process->log();
    }
    return s;
  }

  httplib::Result get_on(const std::string& name, const std::string& path) const {
    httplib::Client c("127.0.0.1", servers.at(name).port);
    c.set_read_timeout(30, 0);
    return c.Get(path, auth("viewer"));
  }
  nlohmann::json json_on(const std::string& name, const std::string& path) const {
    const auto r = get_on(name, path);
    if (!r || r->status != 200) {
      ADD_FAILURE() << name << " GET " << path << ": " << (r ? r->status : -1) << " " << (r ? r->body : "");
      return nullptr;
    }
    return nlohmann::json::parse(r->body);
  }
  nlohmann::json job_on(const std::string& name, std::int64_t job_id) const {
    return json_on(name, "/api/v1/jobs/" + std::to_string(job_id));
  }

  // The first running job whose worker's name starts with `prefix`.
  std::optional<nlohmann::json> wait_running(const std::string& via, const std::string& prefix, std::chrono::seconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      const auto r = get_on(via, "/api/v1/jobs?status=running");
      if (r && r->status == 200) {
        const auto list = nlohmann::json::parse(r->body);
        for (const auto& j : list["jobs"])
          if (j.value("worker", "").rfind(prefix, 0) == 0) return j;
      }
      std::this_thread::sleep_for(20ms);
    }
    return std::nullopt;
  }

  // Whether some connection holds SQLite's write lock on the file now; on
  // PostgreSQL, whether a transaction sits open without a statement (a
  // paused process' one: it holds its row locks and maybe the events' lock).
  bool write_lock_held() const {
    if (storage::is_postgres_location(db.string())) {
      std::this_thread::sleep_for(60ms);  // longer than any live idle moment of a transaction
      return pg_sql(db.string(), "SELECT count(*) FROM pg_stat_activity WHERE state LIKE 'idle in transaction%' "
                                 "AND clock_timestamp() - state_change > interval '50 milliseconds'") != "0";
    }
    sqlite3* h = nullptr;
    if (sqlite3_open_v2(db.string().c_str(), &h, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK) {
      sqlite3_close(h);
      return true;
    }
    const bool held = sqlite3_exec(h, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr) != SQLITE_OK;
    if (!held) sqlite3_exec(h, "ROLLBACK", nullptr, nullptr, nullptr);
    sqlite3_close(h);
    return held;
  }

  // SIGSTOP at a moment the process holds no write transaction: a process
  // paused inside one would hold SQLite's write lock and stall every other
  // writer (PostgreSQL locks rows, not the file). A few tries: after the
  // stop, the lock is free at once unless the paused process holds it.
  bool pause_outside_write(Process& p) {
    for (int attempt = 0; attempt < 50; ++attempt) {
      p.signal(SIGSTOP);
      for (int i = 0; i < 20; ++i) {
        if (!write_lock_held()) return true;
        std::this_thread::sleep_for(5ms);
      }
      p.signal(SIGCONT);
      std::this_thread::sleep_for(37ms);
    }
    return false;
  }

  // The agent of one run, with a spool of its own (agents run side by side).
  std::unique_ptr<Process> stream_run(const fs::path& run_dir, int n) {
    return std::make_unique<Process>(
        std::vector<std::string>{AMBDIAG_AGENT, "replay", run_dir.string(), "--fast", "--domain", std::to_string(domain),
                                 "--partition", partition, "--spool-dir", (dir / ("spool-" + std::to_string(n))).string()},
        env, (dir / ("agent-" + std::to_string(n) + ".log")).string());
  }

  std::string logs() const {
    std::string s;
    for (const auto& [name, srv] : servers) s += "\n--- " + name + " ---\n" + srv.process->log();
    return s;
  }

  // When the job `job_id` of a worker killed at `killed` (its attempt
  // `attempt`) was queued again and claimed by another (seconds), and by
  // whom; nothing if not within 300 s.
  struct JobTakeover {
    double requeued_s = -1, taken_s = -1;
    std::string taker;
  };
  std::optional<JobTakeover> measure_job_takeover(const std::string& via, std::int64_t job_id, int attempt,
                                                  std::chrono::steady_clock::time_point killed) {
    JobTakeover t;
    for (auto deadline = killed + 300s; t.taken_s < 0 && std::chrono::steady_clock::now() < deadline;) {
      const auto j = job_on(via, job_id);
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count();
      if (j.is_object()) {
        if (t.requeued_s < 0 && (j["status"] != "running" || j["attempts"].get<int>() > attempt)) t.requeued_s = s;
        if (j["attempts"].get<int>() > attempt && j["status"] != "queued") {
          t.taken_s = s;
          t.taker = j.value("worker", "(done)");
        }
      }
      std::this_thread::sleep_for(25ms);
    }
    if (t.taken_s < 0) return std::nullopt;
    return t;
  }

  // The late attempt `attempt` of job `job_id` on server `name` (paused
  // past its lease, then woken): its progress, renewal or result refused,
  // as its log says (within `timeout`).
  bool late_attempt_refused(const std::string& name, std::int64_t job_id, int attempt, std::chrono::seconds timeout) {
    const std::string late = "job " + std::to_string(job_id) + " of run ";
    for (auto deadline = std::chrono::steady_clock::now() + timeout; std::chrono::steady_clock::now() < deadline;) {
      const std::string log = servers.at(name).process->log();
      for (auto at = log.find(late); at != std::string::npos; at = log.find(late, at + 1)) {
        const std::string line = log.substr(at, log.find('\n', at) - at);
        if (line.find("(attempt " + std::to_string(attempt) + ")") != std::string::npos &&
            (line.find("result refused") != std::string::npos || line.find("lost its job") != std::string::npos))
          return true;
      }
      std::this_thread::sleep_for(100ms);
    }
    return false;
  }

  // Every server named answers each path the same (one database); read
  // again when a write fell between the reads.
  void expect_same_on(const std::vector<std::string>& names, const std::vector<std::string>& paths) {
    for (const auto& path : paths) {
      bool same = false;
      std::vector<nlohmann::json> answers;
      for (int i = 0; i < 20 && !same; ++i) {
        answers.clear();
        for (const auto& n : names) answers.push_back(json_on(n, path));
        same = std::all_of(answers.begin(), answers.end(), [&](const auto& a) { return a == answers.front(); }) &&
               answers.front() == json_on(names.front(), path);
        if (!same) std::this_thread::sleep_for(200ms);
      }
      std::string shown;
      for (size_t i = 0; i < names.size(); ++i) shown += "\n" + names[i] + ": " + answers[i].dump();
      EXPECT_TRUE(same) << path << shown;
    }
  }

  void run_scenario(const MultiServerScenario& sc) {
    make_tokens();
    const std::string lease = std::to_string(sc.lease_s);
    start_part("A", "ingest,rest");
    start_part("B", "analysis,rest", {"--workers", "1", "--job-lease", lease});
    ASSERT_FALSE(HasFailure()) << logs();
    const auto health_a = json_on("A", "/api/v1/health");
    EXPECT_EQ(health_a["instance"], "A");
    EXPECT_EQ(health_a["parts"], nlohmann::json::array({"ingest", "rest"}));
    EXPECT_TRUE(health_a["jobs"].is_null());
    const auto health_b = json_on("B", "/api/v1/health");
    EXPECT_EQ(health_b["parts"], nlohmann::json::array({"analysis", "rest"}));
    EXPECT_TRUE(health_b["ingest"].is_null());

    EventStream on_a(servers["A"].port, tokens.at("viewer"));
    ASSERT_TRUE(on_a.wait_connected());
    // A writes (it has no analysis part): the model, and its ingest queues the runs.
    const auto model = client_on("A").Put("/api/v1/pumps/P-101/model", auth("engineer"),
                                          read_file_bytes(data_file("reference_pump/plant.json").string()), "application/json");
    ASSERT_TRUE(model && model->status == 200) << (model ? model->body : "") << logs();

    // Half the runs now, half once B is dead, so that C has work to be paused in.
    std::vector<std::string> run_ids;
    std::vector<std::unique_ptr<Process>> agents;
    const auto stream_runs = [&](int from, int to) {
      for (int i = from; i < to; ++i) {
        char started[32];
        std::snprintf(started, sizeof started, "2026-11-21T%02d:%02d:00Z", 10 + i / 60, i % 60);
        run_ids.push_back(std::string(kPump) + "/multi-" + std::to_string(i));
        agents.push_back(stream_run(copy_run("reference_pump/run_ref_1", run_ids.back(), started), i));
      }
    };
    stream_runs(0, sc.runs / 2);

    // B dies while it runs a job (the first: it is the only worker yet);
    // its lease expires and C takes the job.
    const auto on_b = wait_running("A", "B/", 300s);
    ASSERT_TRUE(on_b) << json_on("A", "/api/v1/jobs").dump() << logs();
    start_part("C", "analysis,rest", {"--workers", std::to_string(sc.c_workers), "--job-lease", lease});
    ASSERT_FALSE(HasFailure()) << logs();
    const std::int64_t j1 = (*on_b)["job_id"];
    const int a1 = (*on_b)["attempts"];
    EXPECT_TRUE((*on_b).contains("lease_expires_at")) << on_b->dump();
    servers["B"].process->signal(SIGKILL);
    const auto killed = std::chrono::steady_clock::now();
    EXPECT_EQ(servers["B"].process->wait(10s), -SIGKILL);
    const auto took = measure_job_takeover("A", j1, a1, killed);
    ASSERT_TRUE(took) << job_on("A", j1).dump() << logs();
    std::printf("[ takeover ] lease %.1f s: job %lld of the killed worker queued again after %.2f s, claimed by %s after %.2f s\n",
                sc.lease_s, static_cast<long long>(j1), took->requeued_s, took->taker.c_str(), took->taken_s);
    // Expiry (at most a lease after the last renewal) + the requeue period (half a lease) + polling.
    EXPECT_LE(took->requeued_s, 1.5 * sc.lease_s + 1.5);

    // B comes back (as B2); C is paused past its lease while it runs a job.
    start_part("B2", "analysis,rest", {"--workers", "1", "--job-lease", lease});
    stream_runs(sc.runs / 2, sc.runs);
    const auto on_c = wait_running("A", "C/", 300s);
    ASSERT_TRUE(on_c) << json_on("A", "/api/v1/jobs").dump() << logs();
    const std::int64_t j2 = (*on_c)["job_id"];
    const int a2 = (*on_c)["attempts"];
    ASSERT_TRUE(pause_outside_write(*servers["C"].process)) << "C always held the write lock";
    const auto paused = std::chrono::steady_clock::now();
    nlohmann::json j2_done;
    for (auto deadline = paused + 300s; std::chrono::steady_clock::now() < deadline;) {
      j2_done = job_on("B2", j2);
      if (j2_done["status"] == "done" && j2_done["attempts"].get<int>() > a2) break;
      std::this_thread::sleep_for(50ms);
    }
    const double stolen_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - paused).count();
    servers["C"].process->signal(SIGCONT);
    ASSERT_EQ(j2_done["status"], "done") << j2_done.dump() << logs();
    std::printf("[ takeover ] job %lld of the paused worker done by another after %.2f s (its analysis included)\n",
                static_cast<long long>(j2), stolen_s);
    // C's late attempt: its progress, renewal or result is refused.
    const bool refused = late_attempt_refused("C", j2, a2, 300s);
    EXPECT_TRUE(refused) << logs();

    for (auto& a : agents) EXPECT_EQ(a->wait(300s), 0) << a->log();
    for (const auto& id : run_ids) {
      nlohmann::json an;
      for (auto deadline = std::chrono::steady_clock::now() + 300s; std::chrono::steady_clock::now() < deadline;) {
        an = json_on("A", run_url(id) + "/analysis");
        if (an.value("status", "") == "done") break;
        std::this_thread::sleep_for(200ms);
      }
      EXPECT_EQ(an.value("status", ""), "done") << id << " " << an.dump() << logs();
    }

    // Exactly once: one analysis job per run, done; one trend point per run.
    const auto jobs = json_on("A", "/api/v1/jobs?pump_id=P-101&kind=analysis")["jobs"];
    ASSERT_EQ(jobs.size(), run_ids.size()) << jobs.dump();
    std::set<std::string> runs_of_jobs;
    for (const auto& j : jobs) {
      EXPECT_EQ(j["status"], "done") << j.dump();
      runs_of_jobs.insert(j["run_id"].get<std::string>());
      if (j["job_id"] == j1) {
        EXPECT_GT(j["attempts"].get<int>(), a1);
      }
    }
    EXPECT_EQ(runs_of_jobs.size(), run_ids.size());
    EXPECT_EQ(job_on("A", j2)["result"], j2_done["result"]) << "the paused worker's late result must not replace it";
    const auto trend = json_on("A", "/api/v1/pumps/P-101/trends?series=fit.nrmse&raw=true");
    EXPECT_EQ(trend["series"][0]["count"], sc.runs) << trend.dump();

    // The stream on A saw every analysis, each once, though A ran none.
    for (const auto& id : run_ids) EXPECT_TRUE(on_a.wait_for("job.done", "run_id", id, 30s)) << id << on_a.seen();
    std::map<std::string, int> done_events;
    std::string first_id;
    for (const auto& e : on_a.events()) {
      if (first_id.empty()) first_id = e.id;
      if (e.type == "job.done" && e.data["kind"] == "analysis") ++done_events[e.data["run_id"].get<std::string>()];
    }
    for (const auto& id : run_ids) EXPECT_EQ(done_events[id], 1) << id << on_a.seen();
    // A client resuming on C after A's first event gets the same events, same ids.
    {
      EventStream on_c_resumed(servers["C"].port, tokens.at("viewer"), first_id);
      ASSERT_TRUE(on_c_resumed.wait_connected());
      for (const auto& id : run_ids) EXPECT_TRUE(on_c_resumed.wait_for("job.done", "run_id", id, 30s)) << id;
      std::map<std::string, std::string> ids_on_a;
      for (const auto& e : on_a.events()) ids_on_a[e.id] = e.type;
      for (const auto& e : on_c_resumed.events()) {
        EXPECT_GT(std::stoll(e.id), std::stoll(first_id));
        if (ids_on_a.count(e.id)) {
          EXPECT_EQ(ids_on_a[e.id], e.type) << e.id;
        }
      }
    }

    // Any REST process answers the same for the pump (one database).
    const std::vector<std::string> paths = {"/api/v1/pumps/P-101", "/api/v1/pumps/P-101/runs",
                                            "/api/v1/jobs?pump_id=P-101", "/api/v1/alarms?pump_id=P-101",
                                            "/api/v1/pumps/P-101/trends?series=fit.nrmse&raw=true",
                                            run_url(run_ids.front()) + "/analysis"};
    expect_same_on({"A", "C", "B2"}, paths);
    for (auto& [name, s] : servers)
      if (s.process->running()) s.process->signal(SIGTERM);
    for (auto& [name, s] : servers)
      if (name != "B") {
        EXPECT_EQ(s.process->wait(60s), 0) << name << logs();
      }
  }

  httplib::Client client_on(const std::string& name) const {
    httplib::Client c("127.0.0.1", servers.at(name).port);
    c.set_read_timeout(30, 0);
    return c;
  }
};

}  // namespace ambdiag::testing
