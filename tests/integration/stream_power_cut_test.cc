// The power-cut test, a few cut points (power_cut_fixture.h); the many are
// in stream_power_cut_slow_test.cc.
#include "power_cut_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(PowerCutTest, BlocksAcknowledgedDurableSurviveACutWhileThreeAgentsStream) {
  const CutTally t = cut_streaming(3, 2.0, 2, 7);
  EXPECT_EQ(t.tried, 2);
  t.expect_nothing_lost_or_twice("power cut while streaming (fast)", 1);
}

TEST_F(PowerCutTest, ACutDuringAnAnalysisJobLeavesEveryJobDoneOnce) {
  const CutTally t = cut_jobs(1, 11);
  t.expect_nothing_lost_or_twice("power cut during an analysis job (fast)", 1);
}

}  // namespace
}  // namespace ambdiag::testing
