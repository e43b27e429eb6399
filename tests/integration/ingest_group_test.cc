// Ingest groups in one process (server/ingest_group.h), on a real SQLite
// file and real DDS: who holds a group and when a standby takes it over, and
// the fence, made deterministic by taking the lease from under a holder
// that renews rarely: its next commit rolls back and acknowledges nothing.
#include <stdlib.h>

#include <thread>

#include "ambdiag/core/checksum.h"
#include "ambdiag/core/error.h"
#include "ambdiag/proto/stream.h"
#include "ambdiag/server/ingest_group.h"
#include "hand_agent.h"
#include "stream_fixture.h"

namespace ambdiag::testing {
namespace {

using Clock = std::chrono::steady_clock;

class IngestGroupTest : public StreamTest {
 protected:
  void SetUp() override { setenv("CYCLONEDDS_URI", env["CYCLONEDDS_URI"].c_str(), 1); }

  // A server's ingest side: its historian and its group, run in a thread.
  struct Member {
    explicit Member(storage::Historian h) : historian(std::move(h)) {}
    storage::Historian historian;
    std::unique_ptr<server::IngestGroup> group;
    std::atomic<bool> stop{false};
    std::thread thread;
    ~Member() {
      stop = true;
      if (thread.joinable()) thread.join();
    }
  };

  std::unique_ptr<Member> member(const std::string& name, std::chrono::milliseconds lease,
                                 std::chrono::milliseconds renew_every = {}) {
    auto m = std::make_unique<Member>(storage::Historian::open(db.string()));
    m->historian.checkpoint_in_background(storage::CheckpointOptions{.durable_within = std::chrono::milliseconds(50)});
    server::IngestOptions opt;
    opt.domain = domain;
    opt.partitions = {partition};
    opt.verbose = false;
    m->group = std::make_unique<server::IngestGroup>(
        m->historian, opt, server::IngestGroupOptions{"g", name, lease, renew_every, {}, false});
    m->thread = std::thread([p = m.get()] { p->group->run(p->stop); });
    return m;
  }

  static bool wait_for(const std::function<bool()>& done, std::chrono::milliseconds timeout) {
    for (const auto deadline = Clock::now() + timeout; Clock::now() < deadline;) {
      if (done()) return true;
      std::this_thread::sleep_for(10ms);
    }
    return done();
  }
  static double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }
};

TEST_F(IngestGroupTest, OneHoldsTheOtherStandsByAndTakesOverAtOnceWhenReleased) {
  auto a = member("A", 5s);
  ASSERT_TRUE(wait_for([&] { return a->group->status().holding; }, 5s));
  auto b = member("B", 5s);
  ASSERT_TRUE(wait_for([&] { return b->group->status().holder == "A"; }, 5s));
  std::this_thread::sleep_for(300ms);  // several of B's looks
  EXPECT_FALSE(b->group->status().holding);
  EXPECT_EQ(b->group->health()["role"], "standby");
  EXPECT_EQ(a->group->health()["role"], "holder");
  EXPECT_EQ(a->group->status().epoch, 1);

  // A clean stop releases the group: B does not wait for the 5 s lease.
  const auto stopped = Clock::now();
  a.reset();
  ASSERT_TRUE(wait_for([&] { return b->group->status().holding; }, 5s));
  const double took_s = seconds_since(stopped);
  std::printf("released group taken over after %.3f s (lease 5 s)\n", took_s);
  EXPECT_LT(took_s, 2.5);
  EXPECT_EQ(b->group->status().epoch, 2);
  EXPECT_EQ(b->group->status().takeovers, 1);
}

// A holder that stops renewing (a ghost: taken by a connection that then
// never renews) is taken over once its lease has passed unchanged, not before.
TEST_F(IngestGroupTest, AStandbyWaitsOutTheLeaseOfAHolderThatStoppedRenewing) {
  auto h = storage::Historian::open(db.string());
  const auto seen = h.join_ingest_group("g", partition, 1500);
  ASSERT_TRUE(h.take_ingest_lease(seen, "ghost", partition, 1500));
  const auto since = Clock::now();
  auto b = member("B", 1500ms);
  ASSERT_TRUE(wait_for([&] { return b->group->status().holding; }, 6s));
  const double took_s = seconds_since(since);
  std::printf("lapsed group taken over after %.3f s (lease 1.5 s)\n", took_s);
  EXPECT_GE(took_s, 1.5);
  EXPECT_LT(took_s, 4.0);
  EXPECT_EQ(h.find_ingest_lease("g")->holder, "B");
}

TEST_F(IngestGroupTest, AHolderTakenOverIsFencedInItsNextCommitAndAcknowledgesNothing) {
  // Renewing every 9 s of a 10 s lease: nothing but the commit's own check
  // can tell it that the group was taken.
  auto a = member("A", 10s, 9s);
  ASSERT_TRUE(wait_for([&] { return a->group->status().holding; }, 5s));
  const RunRecording rec = read_run(short_run(0.5, "FENCE/1").string());
  stream::AgentEndpoints agent(domain, partition);
  ASSERT_TRUE(wait_for([&] { return agent.block.matched() > 0; }, 10s));
  send_run_header(agent, rec, "FENCE/1", stream::kProtocolVersion, 512);
  ASSERT_TRUE(wait_status("FENCE/1", storage::RunStatus::receiving, 10s));

  // Another server takes the group (as after a pause of A past its lease).
  auto thief = storage::Historian::open(db.string());
  ASSERT_TRUE(thief.take_ingest_lease(*thief.find_ingest_lease("g"), "thief", partition, 10000));

  const uint32_t n_ch = static_cast<uint32_t>(rec.channels.size());
  ambdiag_stream_SampleBlock b{};
  b.protocol_version = stream::kProtocolVersion;
  b.run_id = const_cast<char*>("FENCE/1");
  b.seq = 0;
  b.first_frame = 0;
  b.n_frames = 512;
  b.checksum_kind = static_cast<uint32_t>(ChecksumKind::xxh64);
  b.checksum = block_checksum(ChecksumKind::xxh64, rec.samples.data(), 512 * n_ch * 4);
  b.payload = stream::borrow_octets(rec.samples.data(), 512 * n_ch * 4);
  ASSERT_TRUE(agent.block.write(b));

  ASSERT_TRUE(wait_for([&] { return a->group->status().lost == 1; }, 10s));
  EXPECT_FALSE(a->group->status().holding);
  const auto& c = a->group->ingest().counters();
  EXPECT_EQ(c.commits_fenced.load(), 1) << a->group->ingest().health().dump();
  EXPECT_EQ(c.blocks_stored.load(), 0);
  EXPECT_EQ(find_run("FENCE/1")->received_chunks, 0);  // rolled back
  // No ack of the block, committed or durable, reached the agent.
  std::this_thread::sleep_for(500ms);
  int acks = 0;
  agent.ack.take(64, [&](const ambdiag_stream_Ack& ack, const dds_sample_info_t&) {
    acks += std::string(ack.run_id) == "FENCE/1" && ack.state == ambdiag_stream_ACK_STORED;
  });
  EXPECT_EQ(acks, 0);
  EXPECT_EQ(thief.find_ingest_lease("g")->holder, "thief");
  // A is a standby now: it left DDS, so the agent sees no server.
  EXPECT_TRUE(wait_for([&] { return agent.block.matched() == 0; }, 5s));
}

TEST_F(IngestGroupTest, AServerReadingOtherPartitionsCannotJoinAHeldGroup) {
  auto a = member("A", 5s);
  ASSERT_TRUE(wait_for([&] { return a->group->status().holding; }, 5s));
  auto h = storage::Historian::open(db.string());
  server::IngestOptions opt;
  opt.domain = domain;
  opt.partitions = {partition + "-other", partition + "-other/*"};
  EXPECT_THROW(server::IngestGroup(h, opt, server::IngestGroupOptions{"g", "C", 5s, {}, {}, false}), InputError);
  EXPECT_EQ(server::partitions_key({"b", "a/*", "b"}), "a/*,b");
  EXPECT_THROW(server::partitions_key({}), InputError);
  EXPECT_THROW(server::partitions_key({"a,b"}), InputError);
}

}  // namespace
}  // namespace ambdiag::testing
