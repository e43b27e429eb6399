#include "trends/prognosis.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "ambdiag/algorithms/numerics/student_t.h"
#include "ambdiag/core/error.h"

namespace ambdiag::server::detail {

std::string to_string(PrognosisStatus s) {
  switch (s) {
    case PrognosisStatus::ok: return "ok";
    case PrognosisStatus::limit_reached: return "limit reached";
    case PrognosisStatus::not_enough_points: return "not enough points";
    case PrognosisStatus::not_trending: return "not trending towards the limit";
  }
  return "not enough points";
}

std::optional<double> default_prognosis_limit(const std::string& series) {
  // A wear clearance twice the design value: the seal's leakage and the
  // rotor's fluid forces have changed enough to plan the overhaul
  // (rest.md's example; the alarm rules may set their own).
  static const std::map<std::string, double> limits = {
      {"fault.balance_piston_wear.clearance_factor", 2.0},
      {"fault.impeller_seal_wear.clearance_factor", 2.0},
  };
  const auto it = limits.find(series);
  return it == limits.end() ? std::nullopt : std::optional<double>(it->second);
}

Prognosis prognose(std::vector<PrognosisPoint> points, double limit, const PrognosisOptions& opt) {
  if (!std::isfinite(limit)) throw InputError("limit: not a finite number");
  if (opt.min_points < 3) throw InputError("prognosis: min_points must be >= 3");
  if (!(opt.level > 0.0 && opt.level < 1.0)) throw InputError("prognosis: level must be in (0, 1)");
  std::sort(points.begin(), points.end(), [](const auto& a, const auto& b) { return a.t_s < b.t_s; });
  Prognosis p;
  p.n = static_cast<int>(points.size());
  if (points.empty()) {
    p.reason = "the series has no points in the range";
    return p;
  }
  p.span_s = points.back().t_s - points.front().t_s;
  if (p.n < opt.min_points || p.span_s < opt.min_span_s) {
    p.reason = "needs at least " + std::to_string(opt.min_points) + " points over at least " +
               std::to_string(static_cast<long long>(opt.min_span_s)) + " s; the range has " + std::to_string(p.n) +
               " over " + std::to_string(static_cast<long long>(p.span_s)) + " s";
    return p;
  }
  p.weighted = std::ranges::all_of(points, [](const auto& x) { return x.sd && *x.sd > 0.0; });
  const auto weight = [&](const PrognosisPoint& x) { return p.weighted ? 1.0 / (*x.sd * *x.sd) : 1.0; };
  // Times relative to the first point keep the sums exact enough.
  const double t0 = points.front().t_s;
  double w_sum = 0, tw = 0, yw = 0;
  for (const auto& x : points) {
    const double w = weight(x);
    w_sum += w;
    tw += w * (x.t_s - t0);
    yw += w * x.value;
  }
  const double tc = tw / w_sum, a = yw / w_sum;  // weighted means: the line passes through them
  double s_tt = 0, s_ty = 0;
  for (const auto& x : points) {
    const double w = weight(x), dt = x.t_s - t0 - tc;
    s_tt += w * dt * dt;
    s_ty += w * dt * (x.value - a);
  }
  const double b = s_ty / s_tt;
  double rss = 0;
  for (const auto& x : points) {
    const double r = x.value - a - b * (x.t_s - t0 - tc);
    rss += weight(x) * r * r;
  }
  const double dof = p.n - 2.0;
  const double sigma2 = rss / dof;
  const double var_a = sigma2 / w_sum, var_b = sigma2 / s_tt;
  p.slope_per_s = b;
  p.slope_sd_per_s = std::sqrt(var_b);
  const double last = points.back().t_s - t0 - tc;
  p.value_at_last = a + b * last;

  // Which side the limit is on: where the line starts.
  const double first = -tc;
  const bool upper = a + b * first < limit;
  if ((upper && !(b > 0.0)) || (!upper && !(b < 0.0))) {
    p.status = PrognosisStatus::not_trending;
    p.reason = "the trend runs away from the limit";
    return p;
  }
  const double q = student_t_quantile(0.5 * (1.0 + opt.level), dof);
  const double d = a - limit;
  // (b^2 - q^2 var_b) u^2 + 2 b d u + d^2 - q^2 var_a = 0, u = t - t_w.
  const double qa = b * b - q * q * var_b, qb = 2.0 * b * d, qc = d * d - q * q * var_a;
  if (!(qa > 0.0)) {
    p.status = PrognosisStatus::not_trending;
    p.reason = "the slope is not significant at the " + std::to_string(static_cast<int>(std::lround(100 * opt.level))) +
               " % level (slope / sd = " + std::to_string(std::fabs(b) / std::sqrt(var_b)) + ")";
    return p;
  }
  const double disc = std::max(0.0, qb * qb - 4.0 * qa * qc);
  const double r1 = (-qb - std::sqrt(disc)) / (2.0 * qa), r2 = (-qb + std::sqrt(disc)) / (2.0 * qa);
  const double u = -d / b;
  p.crossing_s = t0 + tc + u;
  p.lower_s = t0 + tc + std::min(r1, r2);
  p.upper_s = t0 + tc + std::max(r1, r2);
  p.status = u <= last ? PrognosisStatus::limit_reached : PrognosisStatus::ok;
  return p;
}

}  // namespace ambdiag::server::detail
