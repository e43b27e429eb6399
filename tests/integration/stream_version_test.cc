// Protocol versions across the checksum change (docs/streaming.md): a 1.0
// agent (FNV-1a 64, no checksum_kind field) and a 1.1 agent (XXH64) are both
// verified by this server, and an agent configured for FNV-1a (to talk to a
// 1.0 server) is too.
#include <signal.h>
#include <stdlib.h>

#include <algorithm>
#include <cstdio>

#include "ambdiag/core/checksum.h"
#include "ambdiag/proto/stream.h"
#include "hand_agent.h"
#include "stream_fixture.h"

namespace ambdiag::testing {
namespace {

// A run as a protocol 1.0 agent sends it, written by this process: version
// 1.0, block and run checksums FNV-1a 64, checksum_kind never set (0).
TEST_F(StreamTest, AProtocol10AgentWithFnvChecksumsIsVerifiedComplete) {
  auto server = start_server();
  setenv("CYCLONEDDS_URI", env["CYCLONEDDS_URI"].c_str(), 1);
  const RunRecording rec = read_run(short_run(0.25, "OLD/1").string());
  const uint32_t n_ch = static_cast<uint32_t>(rec.channels.size());
  const uint32_t v10 = (1u << 16) | 0u;
  const std::string all(reinterpret_cast<const char*>(rec.samples.data()), rec.samples.size() * 4);
  const size_t block_bytes = 64 * n_ch * 4;
  {
    stream::AgentEndpoints old(domain, partition);
    for (int i = 0; i < 200 && old.block.matched() == 0; ++i) std::this_thread::sleep_for(50ms);
    ASSERT_GT(old.block.matched(), 0);
    send_run_header(old, rec, "OLD/1", v10, 64);
    ASSERT_TRUE(wait_status("OLD/1", storage::RunStatus::receiving, 10s)) << server->log();
    int64_t seq = 0;
    for (size_t at = 0; at < all.size(); at += block_bytes, ++seq) {
      std::string payload = all.substr(at, block_bytes);
      ambdiag_stream_SampleBlock b{};
      b.protocol_version = v10;
      b.run_id = const_cast<char*>("OLD/1");
      b.seq = seq;
      b.first_frame = static_cast<int64_t>(at / (n_ch * 4));
      b.n_frames = static_cast<uint32_t>(payload.size() / (n_ch * 4));
      b.checksum = fnv1a64(payload.data(), payload.size());
      b.payload = stream::borrow_octets(payload.data(), payload.size());
      ASSERT_TRUE(old.block.write(b));
    }
    ASSERT_TRUE(old.block.wait_for_acks(10s));
    ambdiag_stream_RunEnd e{};
    char empty[] = "";
    e.protocol_version = v10;
    e.run_id = const_cast<char*>("OLD/1");
    e.pump_id = const_cast<char*>(rec.pump_id.c_str());
    e.total_frames = rec.frame_count();
    e.n_blocks = seq;
    e.checksum = fnv1a64(all.data(), all.size());
    e.reason = empty;
    // The end may overtake the last commits: the server then answers
    // incomplete and a later end (agents re-send it) finds the run whole.
    for (int i = 0; i < 20 && !wait_status("OLD/1", storage::RunStatus::complete, 1s); ++i) old.end.write(e);
  }
  const auto info = find_run("OLD/1");
  ASSERT_TRUE(info);
  EXPECT_EQ(info->status, storage::RunStatus::complete) << info->status_reason << "\n" << server->log();
  EXPECT_TRUE(stored_samples("OLD/1") == all);
  server->signal(SIGTERM);
  EXPECT_EQ(server->wait(15s), 0) << server->log();
}

// Real agents: the default (XXH64, protocol 1.1) and one configured for
// FNV-1a 64 (what a 1.0 server needs) into the same server.
TEST_F(StreamTest, AgentsOfEitherChecksumKindAreVerifiedSampleForSample) {
  auto server = start_server();
  const fs::path fnv_cfg = write_scratch("fnv.json", R"({"dds": {"checksum": "fnv1a64"}})");
  const fs::path a = short_run(0.5, "KIND/xxh64"), b = short_run(0.5, "KIND/fnv1a64");
  // One after the other: they share the fixture's spool folder (one agent per folder).
  auto agent_a = start_agent(a, {"--fast", "--timeout", "30"});
  EXPECT_EQ(agent_a->wait(60s), 0) << agent_a->log() << "\n--- server ---\n" << server->log();
  auto agent_b = start_agent(b, {"--fast", "--timeout", "30", "--config", fnv_cfg.string()});
  EXPECT_EQ(agent_b->wait(60s), 0) << agent_b->log() << "\n--- server ---\n" << server->log();
  for (const auto& [run_id, run_dir] : {std::pair{"KIND/xxh64", a}, std::pair{"KIND/fnv1a64", b}}) {
    const auto info = find_run(run_id);
    ASSERT_TRUE(info) << run_id;
    EXPECT_EQ(info->status, storage::RunStatus::complete) << run_id << ": " << info->status_reason;
    EXPECT_TRUE(stored_samples(run_id) == read_file_bytes((run_dir / "samples.f32").string())) << run_id;
  }
  // The run checksums the agents reported, by their definitions: FNV-1a 64
  // of samples.f32; the chain of the XXH64 of its 512-frame blocks.
  const auto hex_of = [](uint64_t v) {
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
    return std::string(buf);
  };
  const std::string sb = read_file_bytes((b / "samples.f32").string());
  EXPECT_NE(agent_b->log().find("checksum fnv1a64 " + hex_of(fnv1a64(sb.data(), sb.size()))), std::string::npos)
      << agent_b->log();
  const std::string sa = read_file_bytes((a / "samples.f32").string());
  const size_t block_bytes = 512 * read_run(a.string()).channels.size() * 4;
  uint64_t chain = 0;
  for (size_t at = 0; at < sa.size(); at += block_bytes) {
    const uint64_t h = xxh64(sa.data() + at, std::min(block_bytes, sa.size() - at));
    chain = xxh64(&h, 8, chain);
  }
  EXPECT_NE(agent_a->log().find("checksum xxh64 " + hex_of(chain)), std::string::npos) << agent_a->log();
  server->signal(SIGTERM);
  EXPECT_EQ(server->wait(15s), 0) << server->log();
}

// Protocol 1.2 (durable acks) against 1.1 both ways. An agent speaking 1.1
// deletes a block on any ack: the 1.2 server acknowledges its blocks only
// once durable, so it keeps the new guarantee, and completes.
TEST_F(StreamTest, AnAgentSpeaking11IsAcknowledgedOnlyWhenDurableAndCompletes) {
  auto server = start_server();
  const fs::path old_cfg = write_scratch("v11.json", R"({"dds": {"protocol": "1.1"}})");
  const fs::path run = short_run(0.5, "V/agent-1.1");
  auto agent = start_agent(run, {"--fast", "--timeout", "30", "--config", old_cfg.string()});
  EXPECT_EQ(agent->wait(60s), 0) << agent->log() << "\n--- server ---\n" << server->log();
  const auto info = find_run("V/agent-1.1");
  ASSERT_TRUE(info);
  EXPECT_EQ(info->status, storage::RunStatus::complete) << info->status_reason;
  EXPECT_TRUE(stored_samples("V/agent-1.1") == read_file_bytes((run / "samples.f32").string()));
  server->signal(SIGTERM);
  EXPECT_EQ(server->wait(15s), 0) << server->log();
  // Every block of the run was acknowledged as durable (the server's last line counts them).
  const std::string log = server->log();
  const auto at = log.find(" blocks acknowledged durable");
  ASSERT_NE(at, std::string::npos) << log;
  const auto from = log.rfind(' ', at - 1) + 1;
  EXPECT_GE(std::stoll(log.substr(from, at - from)), info->received_chunks) << log;
}

// A 1.2 agent and a server speaking 1.1 (committed acks, no durable field):
// the agent takes those acks as what that server can say and completes.
TEST_F(StreamTest, ANewAgentCompletesWithAServerSpeaking11) {
  auto server = start_server({"--speak-protocol", "1.1"});
  const fs::path run = short_run(0.5, "V/server-1.1");
  auto agent = start_agent(run, {"--fast", "--timeout", "30"});
  EXPECT_EQ(agent->wait(60s), 0) << agent->log() << "\n--- server ---\n" << server->log();
  const auto info = find_run("V/server-1.1");
  ASSERT_TRUE(info);
  EXPECT_EQ(info->status, storage::RunStatus::complete) << info->status_reason;
  EXPECT_TRUE(stored_samples("V/server-1.1") == read_file_bytes((run / "samples.f32").string()));
  // The agent's spool holds no run: every block was acknowledged (as stored, by a 1.1 server).
  for (const auto& e : fs::directory_iterator(dir / "spool")) EXPECT_FALSE(e.is_directory()) << e.path();
  EXPECT_EQ(server->log().find("acknowledged durable"), std::string::npos);
  server->signal(SIGTERM);
  EXPECT_EQ(server->wait(15s), 0) << server->log();
}

}  // namespace
}  // namespace ambdiag::testing
