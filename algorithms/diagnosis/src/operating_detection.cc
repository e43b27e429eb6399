// Detection and diagnosis against an operating reference: the measured run
// compared with the model at its own speed, its seal drift fitted and
// tested against the normal spread (operating_reference.h).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "ambdiag/algorithms/diagnosis/fault_models.h"
#include "ambdiag/algorithms/diagnosis/operating_reference.h"
#include "ambdiag/algorithms/numerics/chi_square.h"
#include "ambdiag/core/error.h"
#include "diagnosis_internal.h"
#include "operating_internal.h"

namespace ambdiag {

using diagnosis_detail::Aligned;
using diagnosis_detail::AlignedEntry;
using operating_detail::Values;

namespace {

// b and the stated variance of the reference on the measured grid: the same
// grid copies; another one interpolates linearly inside the reference's
// range (the variance of the interpolated b is w0^2 v0 + w1^2 v1).
struct OnGrid {
  std::vector<std::complex<double>> bias;
  std::vector<double> sigma2_bias;  // variance of the interpolated mean of the stated sigma^2 / n
  std::vector<double> sigma2_run;   // stated sigma^2 of one reference run, interpolated
};

OnGrid to_grid(const OperatingEntry& e, const std::vector<double>& ref_hz, const std::vector<double>& hz, double n) {
  OnGrid g;
  const bool same = hz.size() == ref_hz.size() &&
                    std::equal(hz.begin(), hz.end(), ref_hz.begin(), [](double a, double b) { return std::fabs(a - b) <= 1e-9 * std::max(1.0, b); });
  for (size_t l = 0; l < hz.size(); ++l) {
    if (same) {
      g.bias.push_back(e.bias[l]);
      g.sigma2_bias.push_back(e.sigma2[l] / n);
      g.sigma2_run.push_back(e.sigma2[l]);
      continue;
    }
    const double f = hz[l];
    const auto it = std::lower_bound(ref_hz.begin(), ref_hz.end(), f);
    size_t j1 = static_cast<size_t>(it - ref_hz.begin());
    if (j1 == ref_hz.size()) j1 = ref_hz.size() - 1;
    const size_t j0 = j1 == 0 ? 0 : j1 - 1;
    const double span = ref_hz[j1] - ref_hz[j0];
    const double w1 = span > 0.0 ? std::clamp((f - ref_hz[j0]) / span, 0.0, 1.0) : 1.0, w0 = 1.0 - w1;
    g.bias.push_back(w0 * e.bias[j0] + w1 * e.bias[j1]);
    g.sigma2_bias.push_back((w0 * w0 * e.sigma2[j0] + w1 * w1 * e.sigma2[j1]) / n);
    g.sigma2_run.push_back(w0 * e.sigma2[j0] + w1 * e.sigma2[j1]);
  }
  return g;
}

void check_reference(const OperatingReference& ref, const PlantModel& plant, const std::vector<int>& links) {
  if (ref.runs.size() < 2) throw InputError("operating reference: fewer than 2 runs");
  std::vector<std::string> names;
  for (int i : links) names.push_back(plant.links[static_cast<size_t>(i)].name);
  if (names != ref.nuisance_links) {
    std::string a, b;
    for (const auto& x : names) a += " " + x;
    for (const auto& x : ref.nuisance_links) b += " " + x;
    throw InputError("operating reference: it was learnt with the fluid-seal links" + b + ", the plant model has" + a +
                     " (learn it again with this model)");
  }
  const size_t k = names.size();
  if (ref.log_factor_mean.size() != k || ref.log_factor_mean_cov.size() != k * k)
    throw InputError("operating reference: nuisance sizes do not match its links");
}

}  // namespace

namespace operating_detail {

// The normal spread of theta for a new run: (1 + 1/n) Sigma (the run's own
// drift and that of the references' mean) plus the estimates' noise.
Eigen::MatrixXd drift_covariance(const OperatingReference& ref, const Eigen::MatrixXd& estimate_cov) {
  const Eigen::Index k = static_cast<Eigen::Index>(ref.nuisance_links.size());
  const double n = static_cast<double>(ref.runs.size());
  Eigen::MatrixXd s = Eigen::MatrixXd::Constant(k, k, ref.common_sd * ref.common_sd);
  s.diagonal().array() += ref.link_sd * ref.link_sd;
  s *= 1.0 + 1.0 / n;
  for (Eigen::Index i = 0; i < k; ++i)
    for (Eigen::Index j = 0; j < k; ++j) s(i, j) += ref.log_factor_mean_cov[static_cast<size_t>(i * k + j)];
  if (estimate_cov.rows() == k) s += estimate_cov;
  return s;
}

}  // namespace operating_detail

DiagnosisResult diagnose(const PlantModel& plant, const OperatingReference& ref, const FrfData& measured, const DiagnosisOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InputError("diagnosis options: " + why);
  auto progress = [&](const std::string& stage, int done, int total) {
    if (options.progress) options.progress(stage, done, total);
  };
  const std::vector<int> links = fluid_seal_links(plant);
  check_reference(ref, plant, links);
  const Eigen::Index k = static_cast<Eigen::Index>(links.size());
  const double n_runs = static_cast<double>(ref.runs.size());
  const double nu = diagnosis_detail::sigma_dof(measured);
  const double nu_ref = ref.sigma2_dof > 0.0 ? ref.sigma2_dof : std::numeric_limits<double>::infinity();
  const size_t lines = measured.freq_hz.size();
  if (lines == 0) throw InputError("measured FRF: no lines");
  const double lo = ref.freq_hz.front(), hi = ref.freq_hz.back();
  if (measured.freq_hz.front() < lo * (1.0 - 1e-9) || measured.freq_hz.back() > hi * (1.0 + 1e-9))
    throw InputError("measured FRF: lines " + std::to_string(measured.freq_hz.front()) + ".." + std::to_string(measured.freq_hz.back()) +
                     " Hz reach outside the reference's " + std::to_string(lo) + ".." + std::to_string(hi) + " Hz");

  // Aligned data: measured, variance u + v, and b on the measured grid.
  Aligned a;
  a.freq_hz = measured.freq_hz;
  a.speed_rpm = measured.speed_rpm.value_or(plant.speed_rpm);
  operating_detail::RunData run;
  run.skeleton.speed_rpm = a.speed_rpm;
  run.skeleton.freq_hz = a.freq_hz;
  for (const auto& me : measured.entries) {
    const OperatingEntry* re = ref.find(me.output, me.input);
    if (!re) continue;
    if (me.sigma.size() != lines) throw InputError("measured FRF: entry " + me.output + "/" + me.input + " has no sigma column");
    const OnGrid g = to_grid(*re, ref.freq_hz, a.freq_hz, n_runs);
    AlignedEntry e{me.output, me.input, me.h, {}, std::vector<double>(lines), std::vector<double>(lines), 0.0};
    for (size_t l = 0; l < lines; ++l) {
      const double u = re->kappa * me.sigma[l] * me.sigma[l];
      const double v = re->kappa * g.sigma2_bias[l];
      e.var[l] = std::max(u + v, 1e-12 * re->kappa * g.sigma2_run[l]);
      // Both variances may be estimates: the run's with nu dof, the
      // references' mean with sigma2_dof; the relative variance of u + v is
      // 2 (phi^2 / nu + (1 - phi)^2 / nu_ref), phi = u / (u + v).
      const double phi = u / e.var[l];
      const double inv = phi * phi / nu + (1.0 - phi) * (1.0 - phi) / nu_ref;
      double var = 0.0;
      diagnosis_detail::t_moments(1.0, inv > 0.0 ? 1.0 / inv : std::numeric_limits<double>::infinity(), e.t_mean[l], var);
      e.t_var += var;
    }
    run.skeleton.entries.push_back({me.output, me.input, {}, {}, {}});
    run.h.push_back(me.h);
    run.offset.push_back(g.bias);
    std::vector<double> w(lines);
    for (size_t l = 0; l < lines; ++l) w[l] = 1.0 / std::sqrt(e.var[l]);
    run.weight.push_back(std::move(w));
    a.entries.push_back(std::move(e));
  }
  if (a.entries.empty()) throw InputError("measured FRF: shares no entry with the operating reference");

  // The nuisance fit and the residual test.
  progress("nuisance fit", 0, 1);
  Eigen::VectorXd theta_mean = Eigen::VectorXd::Zero(k);
  for (Eigen::Index i = 0; i < k; ++i) theta_mean[i] = ref.log_factor_mean[static_cast<size_t>(i)];
  const operating_detail::NuisanceFit nf = operating_detail::fit_nuisance(plant, links, run, ref.options.log_factor_bound, theta_mean);
  for (size_t e = 0; e < a.entries.size(); ++e)
    for (size_t l = 0; l < lines; ++l) a.entries[e].mean.push_back(nf.at_theta[e][l] + run.offset[e][l]);
  a.fitted_dof = static_cast<int>(k);
  const double alpha_each = k > 0 ? 1.0 - std::sqrt(1.0 - options.alpha) : options.alpha;
  DiagnosisOptions each = options;
  each.alpha = alpha_each;
  DiagnosisResult res;
  diagnosis_detail::detect(a, each, res);
  OperatingTests& ot = res.operating;
  ot.used = true;
  ot.speed_rpm = a.speed_rpm;
  ot.alpha_each = alpha_each;
  ot.residual_statistic = res.statistic;
  ot.residual_threshold = res.threshold;
  ot.residual_dof = res.dof;
  ot.residual_p_value = res.p_value;
  ot.residual_detected = res.detected;

  // The drift test.
  Eigen::VectorXd d = Eigen::VectorXd::Zero(k);
  Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(k, k);
  if (k > 0) {
    for (Eigen::Index i = 0; i < k; ++i) d[i] = nf.theta[i] - ref.log_factor_mean[static_cast<size_t>(i)];
    cov = operating_detail::drift_covariance(ref, nf.cov);
    ot.drift_statistic = d.dot(cov.ldlt().solve(d));
    ot.drift_dof = static_cast<int>(k);
    ot.drift_threshold = chi2_quantile(1.0 - alpha_each, static_cast<double>(k));
    ot.drift_p_value = chi2_sf(ot.drift_statistic, static_cast<double>(k));
    ot.drift_detected = ot.drift_statistic > ot.drift_threshold;
    const Eigen::MatrixXd normal = operating_detail::drift_covariance(ref, Eigen::MatrixXd());
    for (Eigen::Index i = 0; i < k; ++i)
      ot.nuisance.push_back({ref.nuisance_links[static_cast<size_t>(i)], d[i], nf.cov(i, i) > 0.0 ? std::sqrt(nf.cov(i, i)) : 0.0,
                             std::sqrt(normal(i, i))});
  }
  const double p_min = std::min(ot.residual_p_value, ot.drift_p_value);
  res.alpha = options.alpha;
  res.p_value = k > 0 ? 1.0 - std::pow(1.0 - p_min, 2.0) : ot.residual_p_value;
  res.detected = ot.residual_detected || ot.drift_detected;
  res.not_assessed = {"unbalance: needs monitoring runs (1x bearing forces), none given",
                      "misalignment: needs monitoring runs (2x bearing forces), none given"};
  if (res.detected && !ot.residual_detected) {
    // Only the drift fired: the symptoms are those of the change from the
    // reference state (theta_mean), which the fit has absorbed.
    Aligned a0 = a;
    for (size_t e = 0; e < a0.entries.size(); ++e)
      for (size_t l = 0; l < lines; ++l) a0.entries[e].mean[l] = nf.at_start[e][l] + run.offset[e][l];
    DiagnosisResult tmp;
    diagnosis_detail::detect(a0, each, tmp);
    res.symptoms = tmp.symptoms;
    res.isolation = tmp.isolation == "none" ? "multiplicative" : tmp.isolation;
  }
  const FrfFitTarget plain{a.freq_hz, run.h, run.weight, {}};
  Values healthy;
  for (const auto& e : a.entries) healthy.push_back(e.mean);
  res.chi2_before = fit_chi2(plain, healthy);
  res.model_before = diagnosis_detail::as_frf(nf.at_start, a);
  res.nrmse_before = diagnosis_detail::nrmse_of(nf.at_start, a);
  res.chi2_after = res.chi2_before;
  res.nrmse_after = res.nrmse_before;
  res.model_after = res.model_before;
  res.evaluations = nf.evaluations;
  if (!res.detected) res.explained = true;
  // The deciding test's figures in statistic / threshold / dof (the
  // residual test's stay in `operating`).
  auto deciding = [&]() {
    if (k > 0 && ot.drift_p_value < ot.residual_p_value) {
      res.statistic = ot.drift_statistic;
      res.threshold = ot.drift_threshold;
      res.dof = ot.drift_dof;
    }
    return res;
  };
  if (!res.detected || options.detect_only) return deciding();

  res.evaluations += operating_detail::diagnose_faults(plant, links, ref, a, run, nf, options, res);
  return deciding();
}

}  // namespace ambdiag
