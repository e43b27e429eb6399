// RateLimiter: a token bucket per key, on an explicit clock.
#include "rate_limit.h"

#include <gtest/gtest.h>

namespace ambdiag::server::detail {
namespace {

using namespace std::chrono_literals;

TEST(RateLimiter, ABurstIsAllowedThenTheRateAndOtherKeysAreUnaffected) {
  RateLimiter l(2, 4);  // 2/s, bursts of 4
  const auto t0 = RateLimiter::Clock::time_point{} + 1h;
  for (int i = 0; i < 4; ++i) EXPECT_EQ(l.take("token a", t0), 0) << i;
  const double wait = l.take("token a", t0);
  EXPECT_NEAR(wait, 0.5, 1e-9);  // one request refills in 1/2 s
  EXPECT_EQ(l.take("token b", t0), 0);
  EXPECT_GT(l.take("token a", t0 + 400ms), 0);
  EXPECT_EQ(l.take("token a", t0 + 500ms), 0);
  EXPECT_GT(l.take("token a", t0 + 500ms), 0);
  // Idle for long: the bucket is full again, never more than the burst.
  for (int i = 0; i < 4; ++i) EXPECT_EQ(l.take("token a", t0 + 1h), 0) << i;
  EXPECT_GT(l.take("token a", t0 + 1h), 0);
}

TEST(RateLimiter, ZeroIsNoLimit) {
  RateLimiter l(0, 1);
  EXPECT_FALSE(l.enabled());
  for (int i = 0; i < 1000; ++i) EXPECT_EQ(l.take("k"), 0);
}

TEST(RateLimiter, ManyKeysAreForgottenOnceTheirBucketsAreFullAgain) {
  RateLimiter l(10, 2);
  const auto t0 = RateLimiter::Clock::time_point{} + 1h;
  for (int i = 0; i < 20000; ++i)
    EXPECT_EQ(l.take("address " + std::to_string(i), t0 + std::chrono::milliseconds(i)), 0);
  // A key seen long ago starts with a full bucket, as a forgotten one would.
  EXPECT_EQ(l.take("address 0", t0 + 1h), 0);
  EXPECT_EQ(l.take("address 0", t0 + 1h), 0);
  EXPECT_GT(l.take("address 0", t0 + 1h), 0);
}

}  // namespace
}  // namespace ambdiag::server::detail
