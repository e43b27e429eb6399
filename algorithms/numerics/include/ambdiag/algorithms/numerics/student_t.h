// Student's t distribution, for intervals of a regression with an estimated
// scatter: if T ~ t(dof), P(|T| <= student_t_quantile(1 - alpha / 2, dof)) = 1 - alpha.
#pragma once

namespace ambdiag {

// Regularized incomplete beta I_x(a, b), a, b > 0, 0 <= x <= 1 (Numerical
// Recipes 6.4: continued fraction, modified Lentz), relative accuracy ~1e-14.
double regularized_beta(double a, double b, double x);
// P(T <= t) for T ~ t(dof); dof > 0 (need not be an integer).
double student_t_cdf(double t, double dof);
// t with student_t_cdf(t, dof) = p, 0 < p < 1, by bracketing and bisection.
double student_t_quantile(double p, double dof);

}  // namespace ambdiag
