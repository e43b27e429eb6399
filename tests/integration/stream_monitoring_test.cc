// Monitoring snapshots over DDS: this test process is the writer (as an
// agent would be), `ambdiag serve` a real server process. Good snapshots
// land in the historian and on REST; bad ones are rejected and counted.
#include <stdlib.h>

#include <cmath>

#include <httplib.h>

#include "ambdiag/proto/stream.h"
#include "stream_fixture.h"

namespace ambdiag::testing {
namespace {

nlohmann::json get_json(int port, const std::string& path) {
  httplib::Client http("127.0.0.1", port);
  const auto res = http.Get(path.c_str());
  if (!res || res->status != 200) return {};
  return nlohmann::json::parse(res->body);
}

ambdiag_stream_MonitoringSnapshot good_snapshot(char* pump, int64_t time_ns, double k) {
  ambdiag_stream_MonitoringSnapshot m{};
  m.protocol_version = stream::kProtocolVersion;
  m.pump_id = pump;
  m.time_ns = time_ns;
  m.speed_rpm = 2950 + k;
  for (int i = 0; i < 4; ++i) {
    m.force_1x_amp_n[i] = 12.5 + k + i;
    m.force_1x_phase_rad[i] = -1.0 + 0.5 * i;
    m.force_2x_amp_n[i] = 0.75 + 0.125 * i;
    m.force_2x_phase_rad[i] = 0.25 * i;
  }
  for (int b = 0; b < 2; ++b) {
    m.orbit_major_m[b] = 25e-6 + k * 1e-6;
    m.orbit_minor_m[b] = 8e-6;
    m.orbit_center_x_m[b] = 1e-6 * (b + 1);
    m.orbit_center_y_m[b] = -2e-6;
  }
  return m;
}

TEST_F(StreamTest, MonitoringSnapshotsAreStoredServedAndBadOnesRejectedAndCounted) {
  auto server = start_server();
  const int port = rest_port(*server);
  ASSERT_GT(port, 0) << server->log();
  setenv("CYCLONEDDS_URI", env["CYCLONEDDS_URI"].c_str(), 1);

  char pump[] = "P-MON";
  char empty[] = "";
  const int64_t t0 = 1'795'003'200'000'000'000;  // 2026-11-18T12:00:00Z
  {
    stream::AgentEndpoints writer(domain, partition);
    for (int i = 0; i < 200 && writer.monitoring.matched() == 0; ++i) std::this_thread::sleep_for(50ms);
    ASSERT_GT(writer.monitoring.matched(), 0);

    for (int k = 0; k < 3; ++k) ASSERT_TRUE(writer.monitoring.write(good_snapshot(pump, t0 + k * 1'000'000'000LL, k)));
    ASSERT_TRUE(writer.monitoring.write(good_snapshot(pump, t0, 0)));  // the first again: a duplicate

    auto nan_amp = good_snapshot(pump, t0 + 10'000'000'000LL, 0);
    nan_amp.force_1x_amp_n[1] = std::nan("");
    auto negative_orbit = good_snapshot(pump, t0 + 11'000'000'000LL, 0);
    negative_orbit.orbit_major_m[0] = -1e-6;
    auto no_pump = good_snapshot(empty, t0, 0);
    auto other_major = good_snapshot(pump, t0 + 12'000'000'000LL, 0);
    other_major.protocol_version = 7u << 16;
    for (const auto* bad : {&nan_amp, &negative_orbit, &no_pump, &other_major}) ASSERT_TRUE(writer.monitoring.write(*bad));
    ASSERT_TRUE(writer.monitoring.wait_for_acks(10s));

    nlohmann::json j;
    for (int i = 0; i < 100; ++i) {
      j = get_json(port, "/api/v1/health");
      if (j.contains("ingest") && j["ingest"]["rejected"].get<int>() >= 4 &&
          j["ingest"]["monitoring_stored"].get<int>() + j["ingest"]["monitoring_duplicate"].get<int>() >= 4)
        break;
      std::this_thread::sleep_for(100ms);
    }
    ASSERT_TRUE(j.contains("ingest")) << j.dump();
    const auto& in = j["ingest"];
    EXPECT_EQ(in["rejected_by_reason"].value("monitoring", 0), 3) << j.dump();
    EXPECT_EQ(in["rejected_by_reason"].value("version", 0), 1) << j.dump();
    EXPECT_EQ(in["monitoring_stored"], 3) << j.dump();
    EXPECT_EQ(in["monitoring_duplicate"], 1) << j.dump();
  }

  // In the historian, value for value.
  {
    auto h = storage::Historian::open(db.string(), storage::Historian::Mode::read);
    const auto held = h.list_monitoring("P-MON", 0, 100);
    ASSERT_EQ(held.size(), 3u);
    for (int k = 0; k < 3; ++k) {
      const auto& s = held[static_cast<size_t>(k)];
      EXPECT_EQ(s.time_ns, t0 + k * 1'000'000'000LL);
      EXPECT_EQ(s.speed_rpm, 2950.0 + k);
      EXPECT_EQ(s.force_1x_amp_n[3], 12.5 + k + 3);
      EXPECT_EQ(s.orbit_major_m[1], 25e-6 + k * 1e-6);
      EXPECT_EQ(s.orbit_center_y_m[0], -2e-6);
    }
  }
  // On REST.
  const auto r = get_json(port, "/api/v1/pumps/P-MON/monitoring?since=2026-11-18T12:00:01Z");
  ASSERT_EQ(r["snapshots"].size(), 2u) << r.dump();
  EXPECT_EQ(r["snapshots"][0]["time"], "2026-11-18T12:00:01Z");
  EXPECT_EQ(r["snapshots"][1]["force_1x"]["amp_n"]["ax"], 14.5);

  EXPECT_TRUE(server->running());
  server->signal(SIGTERM);
  EXPECT_EQ(server->wait(15s), 0) << server->log();
}

}  // namespace
}  // namespace ambdiag::testing
