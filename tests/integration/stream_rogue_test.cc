// A rogue DDS writer (this test process) sends corrupt, oversized,
// mis-sized, wrong-version and non-finite blocks: the server rejects and
// counts each (GET /api/v1/health), stores the one good block, and keeps
// serving a real agent afterwards.
#include <signal.h>
#include <stdlib.h>

#include <cmath>
#include <cstring>

#include <httplib.h>

#include "ambdiag/core/checksum.h"
#include "ambdiag/proto/stream.h"
#include "hand_agent.h"
#include "stream_fixture.h"

namespace ambdiag::testing {
namespace {

nlohmann::json health(int port) {
  httplib::Client http("127.0.0.1", port);
  const auto res = http.Get("/api/v1/health");
  if (!res || res->status != 200) return {};
  return nlohmann::json::parse(res->body);
}

TEST_F(StreamTest, RogueWriterSamplesAreRejectedCountedAndServerKeepsRunning) {
  auto server = start_server();
  const int port = rest_port(*server);
  ASSERT_GT(port, 0) << server->log();

  setenv("CYCLONEDDS_URI", env["CYCLONEDDS_URI"].c_str(), 1);
  const fs::path good_run = short_run(0.5, "ROGUE/1");
  const RunRecording rec = read_run(good_run.string());
  const uint32_t n_ch = static_cast<uint32_t>(rec.channels.size());
  {
    stream::AgentEndpoints rogue(domain, partition);
    for (int i = 0; i < 200 && rogue.block.matched() == 0; ++i) std::this_thread::sleep_for(50ms);
    ASSERT_GT(rogue.block.matched(), 0);

    send_run_header(rogue, rec, "ROGUE/1", stream::kProtocolVersion, 16);
    ASSERT_TRUE(wait_status("ROGUE/1", storage::RunStatus::receiving, 10s)) << server->log();

    auto send = [&](int64_t seq, uint32_t n_frames, std::string payload, uint64_t checksum, uint32_t version) {
      ambdiag_stream_SampleBlock b{};
      b.protocol_version = version;
      b.run_id = const_cast<char*>("ROGUE/1");
      b.seq = seq;
      b.first_frame = seq * 16;
      b.n_frames = n_frames;
      b.checksum = checksum;
      b.payload = stream::borrow_octets(payload.data(), payload.size());
      ASSERT_TRUE(rogue.block.write(b));
    };
    const std::string good(reinterpret_cast<const char*>(rec.samples.data()), 16 * n_ch * 4);
    const uint64_t good_sum = fnv1a64(good.data(), good.size());
    std::string flipped = good;
    flipped[100] ^= 0x01;
    std::string nan_block = good;
    const float nan = std::nanf("");
    std::memcpy(nan_block.data() + 8, &nan, 4);
    const std::string huge(5u << 20, '\0');

    send(0, 16, good, good_sum, stream::kProtocolVersion);                                         // stored
    send(1, 16, flipped, good_sum, stream::kProtocolVersion);                                      // checksum
    send(1, 17, good, good_sum, stream::kProtocolVersion);                                         // size
    send(1, 16, good, good_sum, (9u << 16));                                                       // version
    send(1, 16, nan_block, fnv1a64(nan_block.data(), nan_block.size()), stream::kProtocolVersion); // non_finite
    send(1, (5u << 20) / (n_ch * 4), huge, fnv1a64(huge.data(), huge.size()), stream::kProtocolVersion);  // oversized
    std::string other = good;
    other[0] ^= 0x02;
    send(0, 16, other, fnv1a64(other.data(), other.size()), stream::kProtocolVersion);             // conflict
    ASSERT_TRUE(rogue.block.wait_for_acks(10s));

    nlohmann::json j;
    for (int i = 0; i < 100; ++i) {
      j = health(port);
      if (j.contains("ingest") && j["ingest"]["rejected"].get<int>() >= 6) break;
      std::this_thread::sleep_for(100ms);
    }
    ASSERT_TRUE(j.contains("ingest")) << j.dump();
    const auto& by = j["ingest"]["rejected_by_reason"];
    for (const char* reason : {"checksum", "size", "version", "non_finite", "oversized", "conflict"})
      EXPECT_EQ(by.value(reason, 0), 1) << reason << ": " << j.dump();
    EXPECT_EQ(j["ingest"]["rejected"], 6);
    EXPECT_EQ(j["ingest"]["blocks_stored"], 1);
  }
  const auto info = find_run("ROGUE/1");
  ASSERT_TRUE(info);
  EXPECT_EQ(info->received_chunks, 1);

  // Still serving: a real agent's run goes through.
  EXPECT_TRUE(server->running());
  const fs::path next = short_run(0.5, "P-101/after-rogue");
  auto agent = start_agent(next, {"--fast", "--timeout", "20"});
  EXPECT_EQ(agent->wait(40s), 0) << agent->log() << "\n--- server ---\n" << server->log();
  server->signal(SIGTERM);
  EXPECT_EQ(server->wait(15s), 0) << server->log();
}

}  // namespace
}  // namespace ambdiag::testing
