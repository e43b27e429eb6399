// Prognosis of a trend series: when its straight-line trend reaches a limit,
// with an interval, or why that cannot be said (rest.md "Trends"; docs/service.md
// "Prognosis").
//
// Model: y_i = a + b (t_i - t_w) + e_i, e_i ~ N(0, sigma^2 / w_i), fitted by
// weighted least squares; w_i = 1 / sd_i^2 when every point has an sd > 0,
// else 1. sigma^2 is estimated from the residuals (sum w r^2 / (n - 2)), so
// sds that understate the run-to-run scatter do not make the interval too
// narrow. The line reaches the limit L at t* = t_w + (L - a) / b. The
// interval is Fieller's: the times t where L lies inside the line's
// confidence band, |a + b (t - t_w) - L| <= q sigma sqrt(1/W + (t - t_w)^2 / S),
// q = t quantile((1 + level) / 2, n - 2), W = sum w, S = sum w (t - t_w)^2.
// It covers the true crossing time with probability `level` under the model,
// and it is a bounded interval exactly when the slope differs from zero at
// that level (|b| / sd(b) > q); otherwise no date is given.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace ambdiag::server::detail {

struct PrognosisPoint {
  double t_s = 0.0;  // seconds on any fixed axis (e.g. since the epoch)
  double value = 0.0;
  std::optional<double> sd;
};

struct PrognosisOptions {
  int min_points = 5;
  double min_span_s = 3600.0;  // first to last point
  double level = 0.9;          // of the interval
};

enum class PrognosisStatus {
  ok,              // trending towards the limit: crossing_s with its interval
  limit_reached,   // the line crossed the limit by the last point (crossing_s in the past)
  not_enough_points,
  not_trending     // slope not significant, or away from the limit
};
std::string to_string(PrognosisStatus s);  // "ok", "limit reached", "not enough points", "not trending towards the limit"

struct Prognosis {
  PrognosisStatus status = PrognosisStatus::not_enough_points;
  std::string reason;  // why not, in words
  int n = 0;
  double span_s = 0.0;
  bool weighted = false;  // by the points' sd
  double slope_per_s = 0.0, slope_sd_per_s = 0.0;
  double value_at_last = 0.0;  // the line at the last point
  std::optional<double> crossing_s, lower_s, upper_s;  // ok and limit_reached
};

// Points in any order. Throws InputError for a non-finite limit or options
// out of range (min_points < 3, level not in (0, 1)).
Prognosis prognose(std::vector<PrognosisPoint> points, double limit, const PrognosisOptions& opt = {});

// The limit a fault parameter's series has by default (e.g. a seal's
// clearance factor 2), nullopt for other series.
std::optional<double> default_prognosis_limit(const std::string& series);

}  // namespace ambdiag::server::detail
