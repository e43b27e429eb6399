#include "ambdiag/algorithms/diagnosis/reference_statistics.h"

#include <algorithm>
#include <cmath>

#include "ambdiag/algorithms/numerics/chi_square.h"
#include "ambdiag/core/error.h"

namespace ambdiag {

const ReferenceEntryStatistics* ReferenceStatistics::find(const std::string& output, const std::string& input) const {
  for (const auto& e : entries)
    if (e.output == output && e.input == input) return &e;
  return nullptr;
}

ReferenceStatistics reference_statistics(const std::vector<FrfData>& runs, const ReferenceOptions& options) {
  if (runs.empty()) throw InputError("reference: no reference FRF given");
  const FrfData& first = runs.front();
  ReferenceStatistics st;
  st.freq_hz = first.freq_hz;
  st.runs = static_cast<int>(runs.size());
  st.speed_rpm = first.speed_rpm.value_or(0.0);
  for (size_t r = 1; r < runs.size(); ++r) {
    const std::string which = "reference " + std::to_string(r + 1);
    if (runs[r].freq_hz.size() != first.freq_hz.size())
      throw InputError(which + ": " + std::to_string(runs[r].freq_hz.size()) + " lines, reference 1 has " +
                       std::to_string(first.freq_hz.size()));
    for (size_t l = 0; l < first.freq_hz.size(); ++l)
      if (std::fabs(runs[r].freq_hz[l] - first.freq_hz[l]) > 1e-9 * std::max(1.0, first.freq_hz[l]))
        throw InputError(which + ": line " + std::to_string(l + 1) + " at " + std::to_string(runs[r].freq_hz[l]) +
                         " Hz, reference 1 at " + std::to_string(first.freq_hz[l]) + " Hz");
    const double rpm = runs[r].speed_rpm.value_or(0.0);
    if (std::fabs(rpm - st.speed_rpm) > 0.01 * std::max(st.speed_rpm, 1.0))
      throw InputError(which + ": speed_rpm " + std::to_string(rpm) + " differs from reference 1 (" + std::to_string(st.speed_rpm) + ")");
  }
  const int n = st.runs;
  const size_t lines = first.freq_hz.size();
  for (const auto& e0 : first.entries) {
    ReferenceEntryStatistics es;
    es.output = e0.output;
    es.input = e0.input;
    std::vector<const FrfEntry*> ent;
    bool sigma = true;
    for (size_t r = 0; r < runs.size(); ++r) {
      const FrfEntry* e = runs[r].find(e0.output, e0.input);
      if (!e) throw InputError("reference " + std::to_string(r + 1) + ": has no entry " + e0.output + "/" + e0.input);
      ent.push_back(e);
      sigma = sigma && e->sigma.size() == lines;
    }
    if (!sigma && n < 2)
      throw InputError("reference: entry " + e0.output + "/" + e0.input + " has no sigma column and there is only one run");
    es.sigma_stated = sigma;
    es.mean.assign(lines, {0.0, 0.0});
    std::vector<double> stated(lines, 0.0), scatter(lines, 0.0);
    for (size_t l = 0; l < lines; ++l) {
      for (const FrfEntry* e : ent) es.mean[l] += e->h[l];
      es.mean[l] /= static_cast<double>(n);
      for (const FrfEntry* e : ent) {
        scatter[l] += std::norm(e->h[l] - es.mean[l]);
        if (sigma) stated[l] += e->sigma[l] * e->sigma[l] / n;
      }
    }
    if (sigma) {
      double s = 0.0;
      int used = 0;
      for (size_t l = 0; l < lines; ++l) {
        if (stated[l] <= 0.0) continue;
        s += 2.0 * scatter[l] / stated[l];
        ++used;
      }
      if (n >= 2 && used > 0) {
        const double dof = 2.0 * (n - 1) * used;
        es.scatter_ratio = s / dof;
        es.scatter_p = chi2_sf(s, dof);
        if (es.scatter_p < options.alpha_scatter) es.kappa = es.scatter_ratio;
      }
      es.var_run.resize(lines);
      for (size_t l = 0; l < lines; ++l) es.var_run[l] = es.kappa * stated[l];
    } else {
      // Between-run scatter per line, pooled over neighbouring lines.
      es.var_run.assign(lines, 0.0);
      const long w = 5;
      for (size_t l = 0; l < lines; ++l) {
        const long lo = std::max<long>(0, static_cast<long>(l) - w);
        const long hi = std::min<long>(static_cast<long>(lines) - 1, static_cast<long>(l) + w);
        double s = 0.0;
        for (long k = lo; k <= hi; ++k) s += scatter[static_cast<size_t>(k)];
        es.var_run[l] = s / ((n - 1) * static_cast<double>(hi - lo + 1));
      }
    }
    es.var_mean.resize(lines);
    for (size_t l = 0; l < lines; ++l) es.var_mean[l] = es.var_run[l] / n;
    st.entries.push_back(std::move(es));
  }
  return st;
}

}  // namespace ambdiag
