// Detection: the chi2 test of the measured FRF against the reference
// statistics, per-entry symptoms, row / column shares and bands.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>

#include "ambdiag/algorithms/numerics/chi_square.h"
#include "ambdiag/core/error.h"
#include "diagnosis_internal.h"

namespace ambdiag::diagnosis_detail {

int Aligned::values() const {
  int n = 0;
  for (const auto& e : entries) n += static_cast<int>(e.h.size());
  return n;
}

double Aligned::t_mean() const {
  double m = 0.0;
  for (const auto& e : entries)
    for (double x : e.t_mean) m += x;
  return m;
}

// Real degrees of freedom of the measured sigma^2 (metadata `sigma_dof`,
// written by `ambdiag frf`); infinity when the file states none.
double sigma_dof(const FrfData& measured) {
  const auto text = measured.meta("sigma_dof");
  if (!text) return std::numeric_limits<double>::infinity();
  char* end = nullptr;
  const double nu = std::strtod(text->c_str(), &end);
  if (end == text->c_str() || *end != '\0' || !std::isfinite(nu))
    throw InputError("measured FRF: sigma_dof: '" + *text + "' is not a number");
  if (!(nu > 4.0))
    throw InputError("measured FRF: sigma_dof: " + *text +
                     " degrees of freedom are too few for the chi2 test (more than 4 needed; measure more periods)");
  return nu;
}

// t = 2 |dH|^2 / (u_hat + v) with u_hat = u chi2_nu / nu: a share phi =
// u / (u + v) of the denominator is estimated, so it has the relative
// variance of a chi2 with nu / phi^2 degrees of freedom, and t / 2 is F(2,
// nu_eff): mean nu / (nu - 2), variance nu^3 / ((nu - 2)^2 (nu - 4)).
// (E 1/u_hat = nu / (nu - 2) / u: without this a healthy run measured over
// 16 periods, nu = 30, would raise T by 7 % and alarm.)
void t_moments(double phi, double nu, double& mean, double& var) {
  const double nu_eff = phi > 0.0 ? nu / (phi * phi) : std::numeric_limits<double>::infinity();
  if (!std::isfinite(nu_eff) || nu_eff > 1e12) {
    mean = 2.0;
    var = 4.0;
    return;
  }
  mean = 2.0 * nu_eff / (nu_eff - 2.0);
  var = 4.0 * nu_eff * nu_eff * nu_eff / ((nu_eff - 2.0) * (nu_eff - 2.0) * (nu_eff - 4.0));
}

namespace {

// A sum with mean mu and variance var as g chi2_h (Satterthwaite):
// g = var / (2 mu), h = 2 mu^2 / var.
struct ScaledChi2 {
  double g = 1.0, h = 1.0;
  ScaledChi2(double mu, double var) : g(var / (2.0 * mu)), h(2.0 * mu * mu / var) {}
  double quantile(double p) const { return g * chi2_quantile(p, h); }
  double sf(double x) const { return chi2_sf(x / g, h); }
};

}  // namespace

Aligned align(const ReferenceStatistics& ref, const FrfData& measured) {
  const size_t lines = ref.freq_hz.size();
  const double nu = sigma_dof(measured);
  if (measured.freq_hz.size() != lines)
    throw InputError("measured FRF: " + std::to_string(measured.freq_hz.size()) + " lines, the references have " +
                     std::to_string(lines));
  for (size_t l = 0; l < lines; ++l)
    if (std::fabs(measured.freq_hz[l] - ref.freq_hz[l]) > 1e-9 * std::max(1.0, ref.freq_hz[l]))
      throw InputError("measured FRF: line " + std::to_string(l + 1) + " at " + std::to_string(measured.freq_hz[l]) +
                       " Hz, the references at " + std::to_string(ref.freq_hz[l]) + " Hz");
  if (measured.speed_rpm && ref.speed_rpm > 0.0 && std::fabs(*measured.speed_rpm - ref.speed_rpm) > 0.01 * ref.speed_rpm)
    throw InputError("measured FRF: speed_rpm " + std::to_string(*measured.speed_rpm) + " differs from the references' " +
                     std::to_string(ref.speed_rpm) + " rpm by more than 1 %");
  Aligned a;
  a.freq_hz = measured.freq_hz;
  a.speed_rpm = measured.speed_rpm.value_or(ref.speed_rpm);
  for (const auto& me : measured.entries) {
    const ReferenceEntryStatistics* r = ref.find(me.output, me.input);
    if (!r) continue;
    AlignedEntry e{me.output, me.input, me.h, r->mean, std::vector<double>(lines), std::vector<double>(lines), 0.0};
    const bool sigma = me.sigma.size() == lines;
    for (size_t l = 0; l < lines; ++l) {
      const double u = sigma ? r->kappa * me.sigma[l] * me.sigma[l] : r->var_run[l];
      e.var[l] = u + r->var_mean[l];
      double var = 0.0;
      t_moments(sigma && e.var[l] > 0.0 ? u / e.var[l] : 0.0, nu, e.t_mean[l], var);
      e.t_var += var;
    }
    // A line without any noise (all zero) cannot be weighted: floor it at
    // a tiny fraction of the entry's typical variance.
    double typical = 0.0;
    for (double v : e.var) typical = std::max(typical, v);
    if (typical <= 0.0) continue;  // no noise information at all: skip the entry
    for (double& v : e.var) v = std::max(v, 1e-12 * typical);
    a.entries.push_back(std::move(e));
  }
  if (a.entries.empty()) throw InputError("measured FRF: shares no entry with the references");
  return a;
}

void detect(const Aligned& a, const DiagnosisOptions& opt, DiagnosisResult& res) {
  const size_t lines = a.freq_hz.size();
  std::vector<double> per_entry(a.entries.size(), 0.0), per_line(lines, 0.0), entry_mean(a.entries.size(), 0.0);
  double total = 0.0, total_mean = 0.0, total_var = 0.0;
  for (size_t e = 0; e < a.entries.size(); ++e) {
    const AlignedEntry& en = a.entries[e];
    for (size_t l = 0; l < lines; ++l) {
      const double t = 2.0 * std::norm(en.h[l] - en.mean[l]) / en.var[l];
      per_entry[e] += t;
      entry_mean[e] += en.t_mean[l];
      per_line[l] += t - en.t_mean[l];  // excess over its expectation
    }
    total += per_entry[e];
    total_mean += entry_mean[e];
    total_var += en.t_var;
  }
  total_mean -= a.fitted_dof;
  total_var -= 2.0 * a.fitted_dof;
  // T is chi2 with 2 x values degrees of freedom when sigma is exact;
  // otherwise the scaled chi2 with T's mean and variance.
  const ScaledChi2 dist(total_mean, total_var);
  res.alpha = opt.alpha;
  res.dof = dist.h;
  res.statistic = total;
  res.threshold = dist.quantile(1.0 - opt.alpha);
  res.p_value = dist.sf(total);
  res.detected = total > res.threshold;

  // Entries that changed, Bonferroni over the entries.
  const double alpha_entry = opt.alpha / static_cast<double>(a.entries.size());
  std::vector<Symptom> entries;
  std::map<std::string, double> row, col;
  double excess_sum = 0.0;
  for (size_t e = 0; e < a.entries.size(); ++e) {
    const ScaledChi2 entry_dist(entry_mean[e], a.entries[e].t_var);
    const double p = entry_dist.sf(per_entry[e]);
    const double excess = std::max(per_entry[e] - entry_mean[e], 0.0);
    row[a.entries[e].output] += excess;
    col[a.entries[e].input] += excess;
    excess_sum += excess;
    if (p < alpha_entry)
      entries.push_back({"entry", a.entries[e].output, a.entries[e].input, per_entry[e], entry_dist.h, p, 0.0, 0.0});
  }
  std::sort(entries.begin(), entries.end(), [](const Symptom& x, const Symptom& y) { return x.statistic - x.dof > y.statistic - y.dof; });
  if (entries.size() > 10) entries.resize(10);
  res.symptoms = entries;
  res.isolation = "none";
  if (!res.detected || excess_sum <= 0.0) return;

  auto top = [](const std::map<std::string, double>& m) {
    std::pair<std::string, double> best{"", -1.0};
    for (const auto& [k, v] : m)
      if (v > best.second) best = {k, v};
    return best;
  };
  const auto [row_name, row_excess] = top(row);
  const auto [col_name, col_excess] = top(col);
  res.symptoms.push_back({"sensor_row", row_name, "", row_excess / excess_sum, 0.0, 1.0, 0.0, 0.0});
  res.symptoms.push_back({"actuator_column", "", col_name, col_excess / excess_sum, 0.0, 1.0, 0.0, 0.0});
  // One row or one column carrying (nearly) all of the change: the
  // measurement chain of that channel, not the machine, changed.
  const double share = 0.8;
  if (row_excess / excess_sum >= share && row_excess >= col_excess)
    res.isolation = "additive_sensor";
  else if (col_excess / excess_sum >= share)
    res.isolation = "additive_actuator";
  else
    res.isolation = "multiplicative";

  // Bands: ten equal parts of the grid, those with >= 10 % of the excess,
  // neighbours merged.
  double line_excess = 0.0;
  for (double x : per_line) line_excess += std::max(x, 0.0);
  if (line_excess <= 0.0) return;
  const size_t parts = std::min<size_t>(10, lines);
  Symptom band{"band", "", "", 0.0, 0.0, 1.0, 0.0, 0.0};
  bool open = false;
  for (size_t b = 0; b < parts; ++b) {
    const size_t l0 = b * lines / parts, l1 = (b + 1) * lines / parts;
    double s = 0.0;
    for (size_t l = l0; l < l1; ++l) s += std::max(per_line[l], 0.0);
    const double sh = s / line_excess;
    if (sh >= 0.1) {
      if (!open) band = {"band", "", "", 0.0, 0.0, 1.0, a.freq_hz[l0], 0.0};
      band.statistic += sh;
      band.band_hi_hz = a.freq_hz[l1 - 1];
      open = true;
    } else if (open) {
      res.symptoms.push_back(band);
      open = false;
    }
  }
  if (open) res.symptoms.push_back(band);
}

}  // namespace ambdiag::diagnosis_detail
