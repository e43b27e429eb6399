// The chi-square distribution, for detection thresholds with a stated
// false-alarm rate: if T ~ chi2(dof), P(T > chi2_quantile(1 - alpha, dof)) = alpha.
#pragma once

namespace ambdiag {

// Regularized lower incomplete gamma P(a, x) (Numerical Recipes 6.2: series
// for x < a + 1, continued fraction otherwise), relative accuracy ~1e-14.
double regularized_gamma_p(double a, double x);
// P(T <= x) for T ~ chi2(dof); dof > 0 (need not be an integer).
double chi2_cdf(double x, double dof);
// x with chi2_cdf(x, dof) = p, 0 < p < 1, by bracketing and bisection on
// the CDF (a Wilson-Hilferty start), so exact to round-off for any dof.
double chi2_quantile(double p, double dof);
// Upper-tail probability P(T > x).
double chi2_sf(double x, double dof);

}  // namespace ambdiag
