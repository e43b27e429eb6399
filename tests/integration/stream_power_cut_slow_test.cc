// The power-cut test at many cut points (power_cut_fixture.h; label slow).
#include "power_cut_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(PowerCutTest, BlocksAcknowledgedDurableSurviveCutsAtManyPointsWhileFourAgentsStream) {
  const CutTally t = cut_streaming(4, 4.0, 24, 2026);
  t.print("power cut while streaming (slow)");
  EXPECT_EQ(t.tried, 24);
  EXPECT_GE(t.cut, 18);
  EXPECT_GT(t.blocks_durable, 0);
  EXPECT_EQ(t.blocks_lost, 0);
  EXPECT_EQ(t.runs_duplicated, 0);
}

TEST_F(PowerCutTest, CutsAtRandomMomentsOfAnalysisJobsLeaveEveryJobDoneOnce) {
  const CutTally t = cut_jobs(5, 2027);
  t.print("power cut during analysis jobs (slow)");
  EXPECT_EQ(t.cut, 5);
  EXPECT_EQ(t.jobs_duplicated, 0);
  EXPECT_EQ(t.runs_duplicated, 0);
}

}  // namespace
}  // namespace ambdiag::testing
