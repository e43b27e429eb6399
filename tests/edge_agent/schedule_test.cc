#include "ambdiag/edge_agent/schedule.h"

#include <gtest/gtest.h>

namespace ambdiag::agent {
namespace {

TEST(Ticker, FirstTickAtStartThenEveryInterval) {
  Ticker t(10.0, 0.0);
  EXPECT_TRUE(t.due(0.0));
  t.done(0.5);
  EXPECT_FALSE(t.due(9.9));
  EXPECT_TRUE(t.due(10.0));
  t.done(10.2);
  EXPECT_DOUBLE_EQ(t.next_s(), 20.0);
}

TEST(Ticker, MissedTicksAreDoneOnceNotInABurst) {
  Ticker t(10.0, 0.0);
  t.done(35.0);  // the work took 35 s: ticks at 10, 20, 30 were missed
  EXPECT_DOUBLE_EQ(t.next_s(), 40.0);
  EXPECT_FALSE(t.due(39.0));
}

TEST(Ticker, ZeroIntervalIsNeverDue) {
  Ticker t(0.0, 0.0);
  EXPECT_FALSE(t.enabled());
  EXPECT_FALSE(t.due(1e9));
}

}  // namespace
}  // namespace ambdiag::agent
