// The power-cut test at many cut points (power_cut_fixture.h; label slow).
#include "power_cut_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(PowerCutTest, BlocksAcknowledgedDurableSurviveCutsAtManyPointsWhileFourAgentsStream) {
  const CutTally t = cut_streaming(4, 4.0, 24, 2026);
  EXPECT_EQ(t.tried, 24);
  EXPECT_GT(t.blocks_durable, 0);
  t.expect_nothing_lost_or_twice("power cut while streaming (slow)", 18);
}

TEST_F(PowerCutTest, CutsAtRandomMomentsOfAnalysisJobsLeaveEveryJobDoneOnce) {
  const CutTally t = cut_jobs(5, 2027);
  t.expect_nothing_lost_or_twice("power cut during analysis jobs (slow)", 5);
}

}  // namespace
}  // namespace ambdiag::testing
