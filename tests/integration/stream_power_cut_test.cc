// The power-cut test, a few cut points (power_cut_fixture.h); the many are
// in stream_power_cut_slow_test.cc.
#include "power_cut_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(PowerCutTest, BlocksAcknowledgedDurableSurviveACutWhileThreeAgentsStream) {
  const CutTally t = cut_streaming(3, 2.0, 2, 7);
  t.print("power cut while streaming (fast)");
  EXPECT_EQ(t.tried, 2);
  EXPECT_GE(t.cut, 1);  // a cut point may lie past the end
  EXPECT_EQ(t.blocks_lost, 0);
  EXPECT_EQ(t.runs_duplicated, 0);
}

TEST_F(PowerCutTest, ACutDuringAnAnalysisJobLeavesEveryJobDoneOnce) {
  const CutTally t = cut_jobs(1, 11);
  t.print("power cut during an analysis job (fast)");
  EXPECT_EQ(t.cut, 1);
  EXPECT_EQ(t.jobs_duplicated, 0);
  EXPECT_EQ(t.runs_duplicated, 0);
}

}  // namespace
}  // namespace ambdiag::testing
