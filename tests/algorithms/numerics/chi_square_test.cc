#include <gtest/gtest.h>

#include <cmath>

#include "ambdiag/algorithms/numerics/chi_square.h"

namespace ambdiag {
namespace {

// Closed forms: chi2(2) is exponential with mean 2, so its p-quantile is
// -2 ln(1 - p); chi2(1) is a squared standard normal, so P(T <= 3.8415) =
// P(|Z| <= 1.95996) = 0.95.
TEST(ChiSquare, QuantilesMatchClosedForms) {
  for (double p : {0.01, 0.5, 0.9, 0.99, 0.999}) EXPECT_NEAR(chi2_quantile(p, 2.0), -2.0 * std::log(1.0 - p), 1e-10);
  EXPECT_NEAR(chi2_quantile(0.95, 1.0), 1.959963984540054 * 1.959963984540054, 1e-9);
  EXPECT_NEAR(chi2_cdf(1.959963984540054 * 1.959963984540054, 1.0), 0.95, 1e-12);
}

// For many degrees of freedom chi2 is nearly normal with mean k and
// variance 2k; the 99 % point lies 2.326 standard deviations above the mean
// (skewness adds about (2/3)(z^2 - 1) ~ 2.9).
TEST(ChiSquare, LargeDofIsNearNormal) {
  const double k = 50000.0;
  const double q = chi2_quantile(0.99, k);
  EXPECT_NEAR(q, k + 2.326347874 * std::sqrt(2 * k) + (2.0 / 3.0) * (2.326347874 * 2.326347874 - 1.0), 0.5);
  EXPECT_NEAR(chi2_sf(q, k), 0.01, 1e-9);
  EXPECT_NEAR(chi2_cdf(q, k) + chi2_sf(q, k), 1.0, 1e-12);
}

}  // namespace
}  // namespace ambdiag
