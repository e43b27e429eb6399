#include "ambdiag/algorithms/identification/modal_features.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "ambdiag/algorithms/identification/mode_labels.h"
#include "ambdiag/algorithms/numerics/chi_square.h"
#include "ambdiag/core/error.h"

namespace ambdiag {

namespace {

struct Found {
  double f, zeta, f_sd, zeta_sd;
  std::string direction;
};

std::vector<Found> identify(const FrfData& frf, const RationalFitOptions& opt) {
  const RationalFitResult fit = fit_rational(frf, opt);
  std::vector<Found> out;
  for (const auto& m : fit.modes) {
    const ModeDescription d = describe_mode(m, fit, frf, nullptr);
    out.push_back({m.f_hz, m.zeta, m.f_sd_hz, m.zeta_sd, d.direction});
  }
  return out;
}

// Closest mode of the same direction within 5 % in frequency.
int closest(const std::vector<Found>& modes, double f, const std::string& dir, const std::vector<bool>& used) {
  int best = -1;
  double d_best = 0.05;
  for (size_t i = 0; i < modes.size(); ++i) {
    if (used[i] || modes[i].direction != dir) continue;
    const double d = std::fabs(modes[i].f - f) / f;
    if (d < d_best) d_best = d, best = static_cast<int>(i);
  }
  return best;
}

// kappa from the between-run scatter of n values against their ML variances.
double scatter_kappa(const std::vector<double>& x, const std::vector<double>& sd, double alpha) {
  const double n = static_cast<double>(x.size());
  double mean = 0.0, q = 0.0, s2 = 0.0;
  for (size_t i = 0; i < x.size(); ++i) mean += x[i] / n, q += sd[i] * sd[i] / n;
  for (double v : x) s2 += (v - mean) * (v - mean) / (n - 1.0);
  if (q <= 0.0) return 1.0;
  const double t = (n - 1.0) * s2 / q;
  return chi2_sf(t, n - 1.0) < alpha ? s2 / q : 1.0;
}

}  // namespace

ModalFeatureReference modal_feature_reference(const std::vector<FrfData>& runs, const RationalFitOptions& fit, double alpha_scatter) {
  if (runs.size() < 2) throw InputError("modal features: need at least two reference runs");
  std::vector<std::vector<Found>> ids;
  for (const auto& r : runs) ids.push_back(identify(r, fit));
  ModalFeatureReference ref;
  ref.runs = static_cast<int>(runs.size());
  for (const auto& anchor : ids.front()) {
    std::vector<Found> same{anchor};
    for (size_t r = 1; r < ids.size(); ++r) {
      const int k = closest(ids[r], anchor.f, anchor.direction, std::vector<bool>(ids[r].size(), false));
      if (k < 0) break;
      same.push_back(ids[r][static_cast<size_t>(k)]);
    }
    if (same.size() != ids.size()) continue;  // not found in every run: not a reliable feature
    std::vector<double> f, fs, z, zs;
    for (const auto& m : same) f.push_back(m.f), fs.push_back(m.f_sd), z.push_back(m.zeta), zs.push_back(m.zeta_sd);
    ModalFeatureStats st;
    st.direction = anchor.direction;
    const double n = static_cast<double>(same.size());
    double qf = 0.0, qz = 0.0;
    for (size_t i = 0; i < same.size(); ++i) {
      st.f_hz += f[i] / n, st.zeta += z[i] / n;
      qf += fs[i] * fs[i] / n, qz += zs[i] * zs[i] / n;
    }
    st.f_kappa = scatter_kappa(f, fs, alpha_scatter);
    st.zeta_kappa = scatter_kappa(z, zs, alpha_scatter);
    st.f_var = st.f_kappa * qf;
    st.zeta_var = st.zeta_kappa * qz;
    ref.modes.push_back(st);
  }
  return ref;
}

ModalFeatureTest modal_feature_test(const ModalFeatureReference& ref, const FrfData& measured, double alpha,
                                    const RationalFitOptions& fit) {
  const std::vector<Found> ids = identify(measured, fit);
  ModalFeatureTest t;
  std::vector<bool> used(ids.size(), false), paired(ref.modes.size(), false);
  const double n = ref.runs;
  // A fault moves modes by far more than the 5 % that pairs healthy runs:
  // pair globally, closest first, same direction, within 30 %.
  std::vector<std::tuple<double, size_t, size_t>> pairs;
  for (size_t k = 0; k < ref.modes.size(); ++k)
    for (size_t i = 0; i < ids.size(); ++i) {
      const double d = std::fabs(ids[i].f - ref.modes[k].f_hz) / ref.modes[k].f_hz;
      if (ids[i].direction == ref.modes[k].direction && d < 0.3) pairs.emplace_back(d, k, i);
    }
  std::sort(pairs.begin(), pairs.end());
  for (const auto& [d, k, i] : pairs) {
    if (paired[k] || used[i]) continue;
    paired[k] = used[i] = true;
    const ModalFeatureStats& m = ref.modes[k];
    const Found& x = ids[i];
    ModalFeatureShift s{static_cast<int>(k), x.f, x.zeta, 0.0, 0.0};
    s.z_f = (x.f - m.f_hz) / std::sqrt(m.f_kappa * x.f_sd * x.f_sd + m.f_var / n);
    s.z_zeta = (x.zeta - m.zeta) / std::sqrt(m.zeta_kappa * x.zeta_sd * x.zeta_sd + m.zeta_var / n);
    t.statistic += s.z_f * s.z_f + s.z_zeta * s.z_zeta;
    t.dof += 2.0;
    t.shifts.push_back(s);
  }
  for (size_t k = 0; k < ref.modes.size(); ++k)
    if (!paired[k]) t.missing.push_back(static_cast<int>(k));
  for (size_t i = 0; i < ids.size(); ++i)
    if (!used[i]) t.shifts.push_back({-1, ids[i].f, ids[i].zeta, 0.0, 0.0});
  if (t.dof > 0.0) {
    t.threshold = chi2_quantile(1.0 - alpha, t.dof);
    t.p_value = chi2_sf(t.statistic, t.dof);
    t.detected = t.statistic > t.threshold;
  }
  // Missing modes are reported, not tested: a weak mode that the order
  // selection drops now and then would otherwise break the stated alpha.
  return t;
}

}  // namespace ambdiag
