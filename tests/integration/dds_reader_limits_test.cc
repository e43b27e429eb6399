// The DDS layer's back-pressure figure: a reliable KEEP_ALL reader whose
// resource limits are full refuses further samples and counts them
// (Reader::rejected_total, which the server reports as
// blocks_rejected_by_dds), and the writer's write() reports the push-back.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <vector>

#include "ambdiag/proto/stream.h"
#include "stream_fixture.h"

namespace ambdiag::testing {
namespace {

using namespace std::chrono_literals;

TEST_F(StreamTest, AFullReliableReaderRefusesAndCountsTheRest) {
  setenv("CYCLONEDDS_URI", env["CYCLONEDDS_URI"].c_str(), 1);
  dds::Participant server_side(domain);
  stream::Topics server_topics(server_side);
  dds::Subscriber sub(server_side, dds::Qos().partitions({partition}));
  dds::Qos small;
  small.reliable().keep_all().resource_limits(2, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  dds::Reader<ambdiag_stream_SampleBlock> reader(sub, server_topics.block, small);

  dds::Participant agent_side(domain);
  stream::Topics agent_topics(agent_side);
  dds::Publisher pub(agent_side, dds::Qos().partitions({partition}));
  dds::Qos q;
  q.reliable(20ms).keep_all();
  dds::Writer<ambdiag_stream_SampleBlock> writer(pub, agent_topics.block, q);
  for (int i = 0; i < 500 && (writer.matched() == 0 || reader.matched() == 0); ++i) std::this_thread::sleep_for(10ms);
  ASSERT_EQ(reader.matched(), 1);
  EXPECT_EQ(reader.rejected_total(), 0);

  std::vector<uint8_t> payload(64, 0);
  char run_id[] = "r";
  auto write = [&](int64_t seq) {
    ambdiag_stream_SampleBlock b{};
    b.protocol_version = stream::kProtocolVersion;
    b.run_id = run_id;
    b.seq = seq;
    b.n_frames = 1;
    b.payload._buffer = payload.data();
    b.payload._length = b.payload._maximum = static_cast<uint32_t>(payload.size());
    return writer.write(b);
  };
  std::vector<int64_t> refused;
  for (int64_t seq = 0; seq < 8; ++seq)
    if (!write(seq)) refused.push_back(seq);
  for (int i = 0; i < 100 && reader.rejected_total() == 0; ++i) std::this_thread::sleep_for(10ms);
  EXPECT_GT(reader.rejected_total(), 0);
  // In one process delivery is local: a refused write reports the push-back
  // to the writer (as the agent sees it), which writes it again later.
  EXPECT_FALSE(refused.empty());
  std::vector<int64_t> got;
  for (int i = 0; i < 300 && got.size() < 8; ++i) {
    reader.take(16, [&](const ambdiag_stream_SampleBlock& b, const dds_sample_info_t&) { got.push_back(b.seq); });
    if (!refused.empty() && write(refused.front())) refused.erase(refused.begin());
    std::this_thread::sleep_for(10ms);
  }
  std::sort(got.begin(), got.end());
  EXPECT_EQ(got, (std::vector<int64_t>{0, 1, 2, 3, 4, 5, 6, 7}));
}

}  // namespace
}  // namespace ambdiag::testing
