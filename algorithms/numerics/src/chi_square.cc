#include "ambdiag/algorithms/numerics/chi_square.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace ambdiag {

namespace {

// Series of P(a, x), x < a + 1.
double gamma_series(double a, double x) {
  double ap = a, sum = 1.0 / a, del = sum;
  for (int n = 0; n < 100000; ++n) {
    ap += 1.0;
    del *= x / ap;
    sum += del;
    if (std::fabs(del) < std::fabs(sum) * 1e-16) break;
  }
  return sum * std::exp(-x + a * std::log(x) - std::lgamma(a));
}

// Continued fraction of Q(a, x) = 1 - P(a, x), x >= a + 1 (modified Lentz).
double gamma_cf(double a, double x) {
  const double tiny = 1e-300;
  double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
  for (int i = 1; i < 100000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::fabs(d) < tiny) d = tiny;
    c = b + an / c;
    if (std::fabs(c) < tiny) c = tiny;
    d = 1.0 / d;
    const double del = d * c;
    h *= del;
    if (std::fabs(del - 1.0) < 1e-16) break;
  }
  return std::exp(-x + a * std::log(x) - std::lgamma(a)) * h;
}

}  // namespace

double regularized_gamma_p(double a, double x) {
  if (!(a > 0.0) || x < 0.0) throw std::invalid_argument("regularized_gamma_p: needs a > 0, x >= 0");
  if (x == 0.0) return 0.0;
  return x < a + 1.0 ? gamma_series(a, x) : 1.0 - gamma_cf(a, x);
}

double chi2_cdf(double x, double dof) { return x <= 0.0 ? 0.0 : regularized_gamma_p(0.5 * dof, 0.5 * x); }

double chi2_sf(double x, double dof) {
  if (x <= 0.0) return 1.0;
  const double a = 0.5 * dof, h = 0.5 * x;
  return h < a + 1.0 ? 1.0 - gamma_series(a, h) : gamma_cf(a, h);
}

double chi2_quantile(double p, double dof) {
  if (!(p > 0.0 && p < 1.0) || !(dof > 0.0)) throw std::invalid_argument("chi2_quantile: needs 0 < p < 1, dof > 0");
  // Wilson-Hilferty start with a normal quantile from bisection on erfc.
  double lo_z = -40.0, hi_z = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo_z + hi_z);
    (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? lo_z : hi_z) = mid;
  }
  const double z = 0.5 * (lo_z + hi_z), v = 2.0 / (9.0 * dof);
  double start = dof * std::pow(std::max(1.0 - v + z * std::sqrt(v), 1e-3), 3.0);
  double lo = start, hi = start;
  while (chi2_cdf(lo, dof) > p) lo *= 0.5;
  while (chi2_cdf(hi, dof) < p) hi = hi * 2.0 + 1.0;
  for (int i = 0; i < 200 && hi - lo > 1e-14 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (chi2_cdf(mid, dof) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace ambdiag
