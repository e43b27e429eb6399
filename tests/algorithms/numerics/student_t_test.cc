// Student t quantiles against tabulated values, and the CDF against the
// closed forms of 1 and 2 degrees of freedom.
#include "ambdiag/algorithms/numerics/student_t.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace ambdiag {
namespace {

TEST(StudentT, QuantilesMatchTheTables) {
  // (p, dof, t) from the standard tables (e.g. NIST/SEMATECH e-Handbook 1.3.6.7.2).
  const struct { double p, dof, t; } table[] = {
      {0.95, 1, 6.314}, {0.95, 10, 1.812}, {0.975, 5, 2.571}, {0.995, 20, 2.845}, {0.9, 100, 1.290}, {0.95, 28, 1.701}};
  for (const auto& row : table) {
    EXPECT_NEAR(student_t_quantile(row.p, row.dof), row.t, 1e-3) << row.p << " " << row.dof;
    EXPECT_NEAR(student_t_quantile(1.0 - row.p, row.dof), -row.t, 1e-3);  // symmetric
  }
}

TEST(StudentT, CdfMatchesTheClosedFormsOfOneAndTwoDegrees) {
  for (double t : {-30.0, -2.0, -0.3, 0.0, 0.7, 4.0, 100.0}) {
    EXPECT_NEAR(student_t_cdf(t, 1), 0.5 + std::atan(t) / std::numbers::pi, 1e-13) << t;  // Cauchy
    EXPECT_NEAR(student_t_cdf(t, 2), 0.5 + t / (2.0 * std::sqrt(2.0 + t * t)), 1e-13) << t;
  }
  EXPECT_NEAR(student_t_quantile(student_t_cdf(1.234, 7.5), 7.5), 1.234, 1e-10);
  EXPECT_THROW(student_t_quantile(1.0, 3), std::invalid_argument);
  EXPECT_THROW(student_t_cdf(1.0, 0), std::invalid_argument);
}

}  // namespace
}  // namespace ambdiag
