// Detection: the chi2 test of the measured FRF against the reference
// statistics, per-entry symptoms, row / column shares and bands.
#include <algorithm>
#include <cmath>
#include <map>

#include "ambdiag/algorithms/chi_square.h"
#include "ambdiag/core/error.h"
#include "diagnosis_internal.h"

namespace ambdiag::diagnosis_detail {

int Aligned::values() const {
  int n = 0;
  for (const auto& e : entries) n += static_cast<int>(e.h.size());
  return n;
}

Aligned align(const ReferenceStatistics& ref, const FrfData& measured) {
  const size_t lines = ref.freq_hz.size();
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
    AlignedEntry e{me.output, me.input, me.h, r->mean, std::vector<double>(lines)};
    const bool sigma = me.sigma.size() == lines;
    for (size_t l = 0; l < lines; ++l) {
      const double u = sigma ? r->kappa * me.sigma[l] * me.sigma[l] : r->var_run[l];
      e.var[l] = u + r->var_mean[l];
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
  std::vector<double> per_entry(a.entries.size(), 0.0), per_line(lines, 0.0);
  double total = 0.0;
  for (size_t e = 0; e < a.entries.size(); ++e) {
    const AlignedEntry& en = a.entries[e];
    for (size_t l = 0; l < lines; ++l) {
      const double t = 2.0 * std::norm(en.h[l] - en.mean[l]) / en.var[l];
      per_entry[e] += t;
      per_line[l] += t - 2.0;  // excess over its expectation
    }
    total += per_entry[e];
  }
  res.alpha = opt.alpha;
  res.dof = 2.0 * static_cast<double>(a.values());
  res.statistic = total;
  res.threshold = chi2_quantile(1.0 - opt.alpha, res.dof);
  res.p_value = chi2_sf(total, res.dof);
  res.detected = total > res.threshold;

  // Entries that changed, Bonferroni over the entries.
  const double entry_dof = 2.0 * static_cast<double>(lines);
  const double alpha_entry = opt.alpha / static_cast<double>(a.entries.size());
  std::vector<Symptom> entries;
  std::map<std::string, double> row, col;
  double excess_sum = 0.0;
  for (size_t e = 0; e < a.entries.size(); ++e) {
    const double p = chi2_sf(per_entry[e], entry_dof);
    const double excess = std::max(per_entry[e] - entry_dof, 0.0);
    row[a.entries[e].output] += excess;
    col[a.entries[e].input] += excess;
    excess_sum += excess;
    if (p < alpha_entry) entries.push_back({"entry", a.entries[e].output, a.entries[e].input, per_entry[e], entry_dof, p, 0.0, 0.0});
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
