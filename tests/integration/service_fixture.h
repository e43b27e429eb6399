// The analysis service with real processes: `ambdiag serve` on a fresh
// historian, tokens made by `ambdiag token add`, runs streamed by
// `ambdiag-agent replay`, conclusions read back over REST with the tokens.
#pragma once

#include <httplib.h>

#include <functional>

#include <nlohmann/json.hpp>

#include "ambdiag/server/rest_server.h"
#include "stream_fixture.h"

namespace ambdiag::testing {

class ServiceTest : public StreamTest {
 protected:
  std::unique_ptr<Process> server;
  int port = 0;
  std::map<std::string, std::string> tokens;  // role -> secret

  // Options every start_service adds (e.g. --anonymous-read for a test
  // whose server is started by a fixture's helper).
  std::vector<std::string> serve_options;

  // Tokens of every role (named after it), then the server (no anonymous
  // reads unless asked).
  void start_service(const std::vector<std::string>& extra = {}) {
    for (const char* role : {"viewer", "operator", "engineer", "admin"})
      if (!tokens.count(role)) tokens[role] = add_token(role, role);
    std::vector<std::string> argv = {AMBDIAG_CLI, "serve", "--db", db.string(), "--http-port", "0", "--domain",
                                     std::to_string(domain), "--partition", partition};
    argv.insert(argv.end(), serve_options.begin(), serve_options.end());
    argv.insert(argv.end(), extra.begin(), extra.end());
    server = std::make_unique<Process>(argv, env, (dir / ("server" + std::to_string(log_n++) + ".log")).string());
    port = rest_port(*server);
    ASSERT_GT(port, 0) << server->log();
  }

  std::string add_token(const std::string& name, const std::string& role) {
    const auto out = dir / ("token" + std::to_string(log_n++) + ".json");
    Process p({AMBDIAG_CLI, "token", "add", "--db", db.string(), "--role", role, "--name", name, "--json"}, env, out.string());
    EXPECT_EQ(p.wait(30s), 0) << p.log();
    const std::string log = p.log();
    const auto brace = log.find('{');
    EXPECT_NE(brace, std::string::npos) << log;
    return nlohmann::json::parse(log.substr(brace))["token"].get<std::string>();
  }

  httplib::Headers auth(const std::string& role) const {
    if (role.empty()) return {};
    return {{"Authorization", "Bearer " + tokens.at(role)}};
  }
  httplib::Client client() const {
    httplib::Client c("127.0.0.1", port);
    c.set_read_timeout(30, 0);
    return c;
  }
  httplib::Result get(const std::string& path, const std::string& role = "viewer") const {
    return client().Get(path, auth(role));
  }
  httplib::Result put(const std::string& path, const std::string& body, const std::string& role = "engineer") const {
    return client().Put(path, auth(role), body, "application/json");
  }
  httplib::Result post(const std::string& path, const std::string& body = "{}", const std::string& role = "engineer") const {
    return client().Post(path, auth(role), body, "application/json");
  }
  static nlohmann::json json_of(const httplib::Result& r) { return nlohmann::json::parse(r->body); }

  static std::string run_url(const std::string& run_id) { return "/api/v1/runs/" + server::url_encode_segment(run_id); }

  // Streams a recording folder with a real agent; true once it is committed complete.
  bool replay(const fs::path& run_dir) {
    auto agent = start_agent(run_dir, {"--fast"});
    return agent->wait(120s) == 0;
  }

  // A copy of a shared run under another run id (and start time), so that a
  // pump has several healthy runs in a test.
  fs::path copy_run(const std::string& shared_run, const std::string& run_id, const std::string& started_at,
                    const std::function<void(RunRecording&)>& change = {}) {
    RunRecording run = read_run(data_file(shared_run).string());
    run.run_id = run_id;
    if (change) change(run);
    run.started_at = started_at;
    const fs::path out = dir / ("copy_" + std::to_string(log_n++));
    write_run(out.string(), run);
    return out;
  }

  // Polls the run's analysis until it is done or failed (or the deadline).
  nlohmann::json wait_analysis(const std::string& run_id, std::chrono::seconds timeout = 180s,
                               int reference_version = 0) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    nlohmann::json last;
    while (std::chrono::steady_clock::now() < deadline) {
      const auto r = get(run_url(run_id) + "/analysis");
      if (r && r->status == 200) {
        last = json_of(r);
        const std::string st = last.value("status", "");
        if ((st == "done" || st == "failed") && last.value("reference_version", 0) >= reference_version) return last;
      }
      std::this_thread::sleep_for(200ms);
    }
    ADD_FAILURE() << "analysis of " << run_id << " not finished in time; last: " << last.dump() << "\n" << server->log();
    return last;
  }
};

}  // namespace ambdiag::testing
