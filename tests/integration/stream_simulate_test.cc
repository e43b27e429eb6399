// `ambdiag-agent simulate` against a real `ambdiag serve` on loopback: the
// simulated identification runs arrive complete in the server (checked
// over REST) and the monitoring snapshots are published on schedule (a DDS
// reader in this process takes them).
#include <signal.h>

#include <httplib.h>

#include <cmath>

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

}  // namespace
}  // namespace ambdiag::testing
