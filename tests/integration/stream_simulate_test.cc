// `ambdiag-agent simulate` against a real `ambdiag serve` on loopback: the
// simulated identification runs arrive complete in the server (checked
// over REST) and the monitoring snapshots are published on schedule (a DDS
// reader in this process takes them).
#include <signal.h>

#include <httplib.h>

#include <cmath>
#include <set>

#include "ambdiag/proto/stream.h"
#include "ambdiag/server/rest_server.h"
#include "stream_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(StreamTest, SimulatedRunsArriveCompleteAndSnapshotsArePublished) {
  setenv("CYCLONEDDS_URI", env["CYCLONEDDS_URI"].c_str(), 1);
  // A monitoring reader in the agents' partition, before the agent starts.
  dds::Participant participant(domain);
  stream::Topics topics(participant);
  dds::Subscriber sub(participant, dds::Qos().partitions({partition}));
  dds::Reader<ambdiag_stream_MonitoringSnapshot> snapshots(sub, topics.monitoring, stream::monitoring_qos());

  auto server = start_server();
  const int port = rest_port(*server);
  ASSERT_GT(port, 0) << server->log();
  // Short runs (2 Hz lines to 600 Hz, 2 + 2 periods of 0.5 s, 5 segments:
  // 10 s of pump), two of them, a snapshot every 0.5 s.
  const fs::path cfg = write_scratch("agent.json", R"({
      "schedule": {"identification_interval_s": 1, "monitoring_interval_s": 0.5, "runs": 2},
      "simulation": {"period_samples": 1024, "f_min_hz": 2, "f_max_hz": 600, "meas_periods": 2,
                     "monitoring_s": 0.25}})");
  const std::vector<std::string> argv = {AMBDIAG_AGENT, "simulate", "--model", data_file("reference_pump/plant.json").string(),
                                         "--pump", "SIM-7", "--fault", "dry_run", "--config", cfg.string(), "--fast",
                                         "--domain", std::to_string(domain), "--partition", partition,
                                         "--spool-dir", (dir / "spool").string(),
                                         "--timeout", "60"};
  Process agent(argv, env, (dir / "agent.log").string());
  ASSERT_EQ(agent.wait(300s), 0) << agent.log() << "\n--- server ---\n" << server->log();

  httplib::Client http("127.0.0.1", port);
  const auto list = http.Get("/api/v1/pumps/SIM-7/runs");
  ASSERT_TRUE(list);
  ASSERT_EQ(list->status, 200) << list->body;
  const auto runs = nlohmann::json::parse(list->body).at("runs");
  ASSERT_EQ(runs.size(), 2u) << list->body;
  for (const auto& r : runs) {
    const std::string id = r.at("run_id");
    const auto one = http.Get("/api/v1/runs/" + server::url_encode_segment(id));
    ASSERT_TRUE(one);
    const auto j = nlohmann::json::parse(one->body);
    EXPECT_EQ(j.at("status"), "complete") << one->body;
    EXPECT_EQ(j.at("n_channels"), 16);
    // 5 segments x 4 periods x 1024 frames.
    EXPECT_EQ(j.at("received_frames"), 5 * 4 * 1024) << one->body;
    const auto samples = http.Get("/api/v1/runs/" + server::url_encode_segment(id) + "/samples.f32");
    ASSERT_TRUE(samples);
    EXPECT_EQ(samples->body.size(), size_t{5 * 4 * 1024} * 16 * 4);
  }

  long n = 0;
  bool plausible = true;
  for (int i = 0; i < 50 && n == 0; ++i) {
    snapshots.take(64, [&](const ambdiag_stream_MonitoringSnapshot& s, const dds_sample_info_t& info) {
      if (!info.valid_data) return;
      ++n;
      plausible = plausible && std::string(s.pump_id) == "SIM-7" && s.protocol_version == stream::kProtocolVersion &&
                  std::abs(s.speed_rpm - 2950) < 1e-9 && s.force_1x_amp_n[0] > 0 && std::isfinite(s.orbit_major_m[0]) &&
                  s.orbit_major_m[0] >= s.orbit_minor_m[0];
    });
    if (n == 0) std::this_thread::sleep_for(100ms);
  }
  EXPECT_GE(n, 2) << agent.log();  // KEEP_LAST 16 per pump keeps the latest ones
  EXPECT_TRUE(plausible);
  EXPECT_NE(agent.log().find("monitoring snapshots published"), std::string::npos) << agent.log();
  server->signal(SIGTERM);
  EXPECT_EQ(server->wait(15s), 0) << server->log();
}

// Operating variability and a fault from run 2: the server stores each
// run's truth ("simulation" in run.json) as sent, and it agrees with the
// run's own speed.
TEST_F(StreamTest, SimulatedRunsCarryTheirTruthIntoTheServer) {
  setenv("CYCLONEDDS_URI", env["CYCLONEDDS_URI"].c_str(), 1);
  auto server = start_server();
  const int port = rest_port(*server);
  ASSERT_GT(port, 0) << server->log();
  const fs::path cfg = write_scratch("agent.json", R"({
      "schedule": {"identification_interval_s": 0.1, "monitoring_interval_s": 0, "runs": 2},
      "simulation": {"period_samples": 1024, "f_min_hz": 2, "f_max_hz": 600, "settle_periods": 1,
                     "meas_periods": 1}})");
  const std::vector<std::string> argv = {AMBDIAG_AGENT, "simulate", "--model", data_file("reference_pump/plant.json").string(),
                                         "--pump", "SIM-8", "--speed-spread", "3", "--seal-drift", "5",
                                         "--fault", "balance_piston_wear=1.5@run2", "--config", cfg.string(), "--fast",
                                         "--domain", std::to_string(domain), "--partition", partition,
                                         "--spool-dir", (dir / "spool").string(), "--timeout", "60"};
  Process agent(argv, env, (dir / "agent.log").string());
  ASSERT_EQ(agent.wait(300s), 0) << agent.log() << "\n--- server ---\n" << server->log();
  EXPECT_NE(agent.log().find("loop rebuilt in"), std::string::npos) << agent.log();

  httplib::Client http("127.0.0.1", port);
  const auto list = http.Get("/api/v1/pumps/SIM-8/runs");
  ASSERT_TRUE(list);
  const auto runs = nlohmann::json::parse(list->body).at("runs");
  ASSERT_EQ(runs.size(), 2u) << list->body;
  std::set<int64_t> seen;
  for (const auto& r : runs) {
    const auto one = http.Get("/api/v1/runs/" + server::url_encode_segment(r.at("run_id").get<std::string>()));
    ASSERT_TRUE(one);
    const auto j = nlohmann::json::parse(one->body);
    const auto& truth = j.at("header").at("simulation");
    const int64_t n = truth.at("run").get<int64_t>();
    seen.insert(n);
    EXPECT_EQ(truth.at("speed_rpm").get<double>(), j.at("speed_rpm").get<double>()) << one->body;
    EXPECT_NEAR(truth.at("speed_rpm").get<double>(), 2950, 0.03 * 2950);
    EXPECT_EQ(truth.at("seal_factors").size(), 2u);
    EXPECT_EQ(truth.at("faults").at(0).at("active").get<bool>(), n == 2) << one->body;
  }
  EXPECT_EQ(seen, (std::set<int64_t>{1, 2}));
  server->signal(SIGTERM);
  EXPECT_EQ(server->wait(15s), 0) << server->log();
}

TEST_F(StreamTest, MalformedFaultScheduleIsAUsageError) {
  for (const std::string bad : {"balance_piston_wear=1.3@5", "balance_piston_wear=1.0..1.6", "bearing_fire"}) {
    Process agent({AMBDIAG_AGENT, "simulate", "--model", data_file("reference_pump/plant.json").string(), "--pump",
                   "SIM-9", "--fault", bad, "--spool-dir", (dir / "spool").string()},
                  env, (dir / ("bad" + std::to_string(log_n++) + ".log")).string());
    EXPECT_EQ(agent.wait(30s), 2) << bad << "\n" << agent.log();
    EXPECT_NE(agent.log().find(bad), std::string::npos) << agent.log();
  }
}

}  // namespace
}  // namespace ambdiag::testing
