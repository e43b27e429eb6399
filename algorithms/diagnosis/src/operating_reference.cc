// Learning the operating reference: the nuisance fitted per reference run,
// the model's own error b, the normal spread of the nuisance and the noise
// scale kappa (operating_reference.h).
#include "ambdiag/algorithms/diagnosis/operating_reference.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "ambdiag/algorithms/diagnosis/fault_models.h"
#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/algorithms/numerics/chi_square.h"
#include "ambdiag/core/error.h"
#include "diagnosis_internal.h"
#include "frf_fit_target.h"
#include "operating_internal.h"

namespace ambdiag {

bool OperatingReferenceOptions::is_valid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!(common_sd_floor > 0.0 && common_sd_floor < 1.0)) return fail("common_sd_floor must be in (0, 1)");
  if (!(link_sd_floor > 0.0 && link_sd_floor < 1.0)) return fail("link_sd_floor must be in (0, 1)");
  if (!(log_factor_bound > 0.0 && log_factor_bound <= 5.0)) return fail("log_factor_bound must be in (0, 5]");
  if (!(alpha_scatter > 0.0 && alpha_scatter < 0.5)) return fail("alpha_scatter must be in (0, 0.5)");
  if (passes < 1 || passes > 10) return fail("passes must be in 1..10");
  return true;
}

const OperatingEntry* OperatingReference::find(const std::string& output, const std::string& input) const {
  for (const auto& e : entries)
    if (e.output == output && e.input == input) return &e;
  return nullptr;
}

namespace operating_detail {

PlantModel with_nuisance(const PlantModel& plant, const std::vector<int>& links, const Eigen::VectorXd& theta) {
  PlantModel p = plant;
  for (size_t k = 0; k < links.size(); ++k) scale_link(p.links.at(static_cast<size_t>(links[k])), std::exp(theta[static_cast<Eigen::Index>(k)]));
  return p;
}

Values model_values(const PlantModel& plant, const FrfData& skeleton) {
  // The diagnosis' synthesis (diagnosis_internal.h ModelGrid): the reference
  // and every later run must use the same one, so that its small error is
  // part of b.
  FrfSynthesisOptions o;
  o.method = FrfMethod::modal;
  o.modal_basis = ModalBasis::krylov;
  o.damping.modes = StructuralDampingOptions::Modes::band;
  const FrfData f = model_frf_like(plant, skeleton, o);
  Values v;
  for (const auto& e : f.entries) v.push_back(e.h);
  return v;
}

NuisanceFit fit_nuisance(const PlantModel& plant, const std::vector<int>& links, const RunData& run, double bound,
                         const Eigen::VectorXd& start) {
  NuisanceFit f;
  const Eigen::Index k_links = static_cast<Eigen::Index>(links.size());
  const Eigen::VectorXd th0 = k_links ? Eigen::VectorXd(start.cwiseMax(-bound).cwiseMin(bound)) : Eigen::VectorXd();
  f.at_start = model_values(k_links ? with_nuisance(plant, links, th0) : plant, run.skeleton);
  f.evaluations = 1;
  FrfFitTarget target{run.skeleton.freq_hz, run.h, run.weight, run.offset};
  if (target.offset.empty())
    for (const auto& e : run.h) target.offset.emplace_back(e.size(), std::complex<double>(0.0, 0.0));
  if (k_links == 0) {
    f.chi2 = fit_chi2(target, f.at_start);
    f.at_theta = f.at_start;
    return f;
  }
  // Difference Jacobian at the start: the model is nearly linear over a few
  // percent, so the first Gauss-Newton step lands close to the optimum.
  const double step = 1e-3;
  const int values = target.values();
  Eigen::MatrixXd jac0(2 * values, k_links);
  for (Eigen::Index k = 0; k < k_links; ++k) {
    Eigen::VectorXd th = th0;
    th[k] += th0[k] + step > bound ? -step : step;
    const double h = th[k] - th0[k];
    Values v = model_values(with_nuisance(plant, links, th), run.skeleton);
    ++f.evaluations;
    Eigen::Index row = 0;
    for (size_t e = 0; e < v.size(); ++e)
      for (size_t l = 0; l < v[e].size(); ++l) {
        v[e][l] = (v[e][l] - f.at_start[e][l]) / h;
        const std::complex<double> d = run.weight[e][l] * v[e][l];
        jac0(row++, k) = d.real();
        jac0(row++, k) = d.imag();
      }
    f.jacobian.push_back(std::move(v));
  }
  std::vector<std::pair<Eigen::VectorXd, Values>> memo;
  auto model = [&](const std::vector<double>& thv) -> Values {
    const Eigen::VectorXd th = Eigen::Map<const Eigen::VectorXd>(thv.data(), static_cast<Eigen::Index>(thv.size()));
    if (th == th0) return f.at_start;
    for (const auto& [t, v] : memo)
      if (t == th) return v;
    memo.emplace_back(th, model_values(with_nuisance(plant, links, th), run.skeleton));
    ++f.evaluations;
    return memo.back().second;
  };
  std::vector<FitParameter> params;
  for (Eigen::Index k = 0; k < k_links; ++k) params.push_back({"log_factor", th0[k], -bound, bound});
  LeastSquaresOptions o = secant_fit_options(20, 1e-9, 1e-7);
  o.jacobian0 = jac0;
  const LeastSquaresResult r = fit_parameters(model, target, params, o);
  f.theta = Eigen::Map<const Eigen::VectorXd>(r.x.data(), k_links);
  f.cov = r.covariance;
  f.chi2 = r.chi2;
  f.at_theta = model(r.x);
  return f;
}

}  // namespace operating_detail

using namespace operating_detail;

namespace {

std::string run_name(const FrfData& run, size_t i) {
  const auto id = run.meta("run_id");
  return "reference run " + std::to_string(i + 1) + (id ? " (" + *id + ")" : "");
}

bool same_hz(double a, double b) { return std::fabs(a - b) <= 1e-9 * std::max(1.0, std::max(a, b)); }

// Index of the line of `hz` (sorted) at f, or -1.
long line_at(const std::vector<double>& hz, double f) {
  const auto it = std::lower_bound(hz.begin(), hz.end(), f * (1.0 - 1e-9) - 1e-12);
  return it != hz.end() && same_hz(*it, f) ? static_cast<long>(it - hz.begin()) : -1;
}

// Runs a and b on one excitation grid that each may have dropped lines of
// (the estimators drop a line a speed harmonic falls on, and runs at other
// speeds drop other lines): every line of a is either a line of b or at
// least 0.9 x a's own line spacing there away from every line of b, i.e. a
// gap of b. A line shifted off the grid (closer to one of b's than a's
// spacing) is not that; "" when they agree, else what is wrong.
std::string grid_mismatch(const std::vector<double>& a, const std::vector<double>& b) {
  for (size_t l = 0; l < a.size(); ++l) {
    const double f = a[l];
    const auto it = std::lower_bound(b.begin(), b.end(), f);
    double nearest = std::numeric_limits<double>::infinity(), at = f;
    if (it != b.end() && std::fabs(*it - f) < nearest) nearest = std::fabs(*it - f), at = *it;
    if (it != b.begin() && std::fabs(*(it - 1) - f) < nearest) nearest = std::fabs(*(it - 1) - f), at = *(it - 1);
    if (same_hz(at, f)) continue;
    double spacing = std::numeric_limits<double>::infinity();
    if (l > 0) spacing = std::min(spacing, f - a[l - 1]);
    if (l + 1 < a.size()) spacing = std::min(spacing, a[l + 1] - f);
    if (nearest < 0.9 * spacing)
      return "line " + std::to_string(l + 1) + " at " + std::to_string(f) + " Hz is off the grid, nearest line " +
             std::to_string(at) + " Hz";
  }
  return "";
}

// Grid, entries and sigma columns of every run. The runs may lack a few
// lines of their common grid (see grid_mismatch); the lines every run has
// are returned, the grid the reference is learnt on. At least 90 % of each
// run's lines must be on it: the few dropped lines, not another grid.
std::vector<double> check_runs(const std::vector<FrfData>& runs) {
  if (runs.size() < 2)
    throw InputError("operating reference: " + std::to_string(runs.size()) + " reference run(s), at least 2 needed");
  const FrfData& first = runs.front();
  for (size_t r = 0; r < runs.size(); ++r)
    if (runs[r].freq_hz.empty()) throw InputError(run_name(runs[r], r) + ": no lines");
  for (size_t r = 1; r < runs.size(); ++r)
    for (size_t q = 0; q < r; ++q) {
      std::string why = grid_mismatch(runs[r].freq_hz, runs[q].freq_hz);
      if (why.empty()) why = grid_mismatch(runs[q].freq_hz, runs[r].freq_hz);
      if (!why.empty()) throw InputError(run_name(runs[r], r) + ": not on the grid of run " + std::to_string(q + 1) + ": " + why);
    }
  std::vector<double> common;
  for (double f : first.freq_hz) {
    bool everywhere = true;
    for (size_t r = 1; r < runs.size() && everywhere; ++r) everywhere = line_at(runs[r].freq_hz, f) >= 0;
    if (everywhere) common.push_back(f);
  }
  for (size_t r = 0; r < runs.size(); ++r) {
    const FrfData& run = runs[r];
    const std::string which = run_name(run, r);
    if (static_cast<double>(common.size()) < 0.9 * static_cast<double>(run.freq_hz.size()))
      throw InputError(which + ": " + std::to_string(run.freq_hz.size()) + " lines, only " + std::to_string(common.size()) +
                       " of them in every reference run");
    if (run.entries.size() != first.entries.size())
      throw InputError(which + ": " + std::to_string(run.entries.size()) + " entries, run 1 has " + std::to_string(first.entries.size()));
    for (const auto& e0 : first.entries) {
      const FrfEntry* e = run.find(e0.output, e0.input);
      if (!e) throw InputError(which + ": has no entry " + e0.output + "/" + e0.input);
      if (e->sigma.size() != run.freq_hz.size())
        throw InputError(which + ": entry " + e0.output + "/" + e0.input + " has no sigma column (the noise level is needed)");
      for (double s : e->sigma)
        if (!(s > 0.0) || !std::isfinite(s))
          throw InputError(which + ": entry " + e0.output + "/" + e0.input + ": sigma must be finite and > 0");
    }
  }
  return common;
}

// The run on the lines `hz` (each one of its lines, check_runs).
FrfData on_lines(const FrfData& run, const std::vector<double>& hz) {
  if (run.freq_hz.size() == hz.size()) return run;
  FrfData out = run;
  out.freq_hz = hz;
  for (size_t e = 0; e < run.entries.size(); ++e) {
    const FrfEntry& in = run.entries[e];
    FrfEntry& o = out.entries[e];
    o.h.clear(), o.sigma.clear(), o.coh.clear();
    for (double f : hz) {
      const auto l = static_cast<size_t>(line_at(run.freq_hz, f));
      o.h.push_back(in.h[l]);
      if (!in.sigma.empty()) o.sigma.push_back(in.sigma[l]);
      if (!in.coh.empty()) o.coh.push_back(in.coh[l]);
    }
  }
  return out;
}

// Normal spread of theta: a common drift of all links (sd_c) plus each
// link's own (sd_l), from the centred estimates, pooled; see the header.
void learn_spread(const std::vector<Eigen::VectorXd>& theta, const Eigen::VectorXd& mean, OperatingReference& ref) {
  const double n = static_cast<double>(theta.size());
  const Eigen::Index k = mean.size();
  double s_common = 0.0, s_link = 0.0;
  for (const auto& t : theta) {
    const Eigen::VectorXd d = t - mean;
    const double c = d.mean();
    s_common += c * c;
    s_link += (d.array() - c).square().sum();
  }
  s_common /= (n - 1.0);
  if (k >= 2) {
    s_link /= (n - 1.0) * static_cast<double>(k - 1);
    // The common mean of K links carries 1/K of each link's own variance.
    ref.link_sd_estimate = std::sqrt(s_link);
    ref.common_sd_estimate = std::sqrt(std::max(0.0, s_common - s_link / static_cast<double>(k)));
  } else {
    ref.link_sd_estimate = 0.0;  // one link: its own and the common drift are one
    ref.common_sd_estimate = std::sqrt(s_common);
  }
  ref.common_sd = std::max(ref.common_sd_estimate, ref.options.common_sd_floor);
  ref.link_sd = std::max(ref.link_sd_estimate, ref.options.link_sd_floor);
}

}  // namespace

OperatingReference learn_operating_reference(const PlantModel& plant, const std::vector<FrfData>& all_lines,
                                             const OperatingReferenceOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InputError("operating reference options: " + why);
  // Learnt on the lines every reference run has (runs at other speeds
  // dropped other lines a speed harmonic fell on); a later run's lines
  // between them get b interpolated (operating_detection.cc).
  const std::vector<double> common = check_runs(all_lines);
  std::vector<FrfData> runs;
  for (const auto& r : all_lines) runs.push_back(on_lines(r, common));
  OperatingReference ref;
  ref.options = options;
  const std::vector<int> links = fluid_seal_links(plant);
  for (int i : links) ref.nuisance_links.push_back(plant.links[static_cast<size_t>(i)].name);
  const FrfData& first = runs.front();
  ref.freq_hz = first.freq_hz;
  const size_t n_runs = runs.size(), n_ent = first.entries.size(), lines = first.freq_hz.size();
  const double n = static_cast<double>(n_runs);

  // Degrees of freedom of the mean stated variance: each run's sigma^2 may
  // be an estimate (`sigma_dof`), and the mean of n such has n^2 / sum(1 /
  // nu_i) (Satterthwaite).
  double inv_nu = 0.0;
  for (size_t r = 0; r < n_runs; ++r) {
    try {
      inv_nu += 1.0 / diagnosis_detail::sigma_dof(runs[r]);
    } catch (const InputError& e) {
      throw InputError(run_name(runs[r], r) + ": " + e.what());
    }
  }
  const double nu_mean = inv_nu > 0.0 ? n * n / inv_nu : std::numeric_limits<double>::infinity();
  ref.sigma2_dof = std::isfinite(nu_mean) ? nu_mean : 0.0;

  // Every run's data in the first run's entry order.
  std::vector<RunData> data(n_runs);
  for (size_t r = 0; r < n_runs; ++r) {
    RunData& d = data[r];
    d.skeleton.speed_rpm = runs[r].speed_rpm.value_or(plant.speed_rpm);
    d.skeleton.freq_hz = first.freq_hz;
    for (const auto& e0 : first.entries) {
      const FrfEntry* e = runs[r].find(e0.output, e0.input);
      d.skeleton.entries.push_back({e0.output, e0.input, {}, {}, {}});
      d.h.push_back(e->h);
      std::vector<double> w(lines);
      for (size_t l = 0; l < lines; ++l) w[l] = 1.0 / e->sigma[l];
      d.weight.push_back(std::move(w));
    }
  }

  // theta per run with b = 0 first (absolute: b and a common shift of all
  // theta_i are the same to first order, so the start decides, and b = 0
  // leaves in b only what no seal drift explains; b absorbing the
  // references' mean drift instead would be right at their speeds only:
  // (J(s) - J(s_ref)) theta_mean at another, 3 sd of the residual test for a
  // 3 % drift and a 4 % speed step), then b, alternated.
  std::vector<Values> model_at(n_runs);
  Values bias;
  auto update_bias = [&]() {
    bias.assign(n_ent, std::vector<std::complex<double>>(lines, {0.0, 0.0}));
    for (size_t r = 0; r < n_runs; ++r)
      for (size_t e = 0; e < n_ent; ++e)
        for (size_t l = 0; l < lines; ++l) bias[e][l] += (data[r].h[e][l] - model_at[r][e][l]) / n;
  };
  std::vector<NuisanceFit> fits(n_runs);
  for (int pass = 0; pass < options.passes; ++pass) {
    for (size_t r = 0; r < n_runs; ++r) {
      data[r].offset = bias;
      const Eigen::VectorXd start = pass > 0 ? fits[r].theta : Eigen::VectorXd::Zero(static_cast<Eigen::Index>(links.size()));
      try {
        fits[r] = fit_nuisance(plant, links, data[r], options.log_factor_bound, start);
      } catch (const InputError& e) {
        throw InputError(run_name(runs[r], r) + ": " + e.what());
      }
      model_at[r] = fits[r].at_theta;
    }
    update_bias();
  }

  // The nuisance's centre and spread.
  const Eigen::Index k = static_cast<Eigen::Index>(links.size());
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(k);
  Eigen::MatrixXd mean_cov = Eigen::MatrixXd::Zero(k, k);
  std::vector<Eigen::VectorXd> theta;
  for (const auto& f : fits) {
    theta.push_back(f.theta);
    mean += f.theta / n;
    if (k > 0) mean_cov += f.cov / (n * n);
  }
  if (k > 0) learn_spread(theta, mean, ref);
  ref.log_factor_mean.assign(mean.data(), mean.data() + k);
  for (Eigen::Index i = 0; i < k; ++i)
    for (Eigen::Index j = 0; j < k; ++j) ref.log_factor_mean_cov.push_back(mean_cov(i, j));

  // Runs, and kappa per entry from the residual scatter: sum_i |r_i|^2 with
  // r_i = H_i - M_i - b is (n - 1) / n of the noise variance summed, a chi2
  // with d1 = 2 (n - 1) dof per line if sigma is right (the few nuisance
  // parameters per run are negligible against L). Divided by the mean stated
  // variance with d2 = sigma2_dof it is d1 F(d1, d2) per line: mean d1 d2 /
  // (d2 - 2), 2 % above d1 for three runs of nu = 30, which without this
  // raised kappa on a tenth of the entries and cut the false alarms to a
  // third of alpha.
  const double d1 = 2.0 * (n - 1.0), d2 = nu_mean;
  const double line_mean = std::isfinite(d2) ? d1 * d2 / (d2 - 2.0) : d1;
  const double line_var =
      std::isfinite(d2) ? d1 * d1 * 2.0 * d2 * d2 * (d1 + d2 - 2.0) / (d1 * (d2 - 2.0) * (d2 - 2.0) * (d2 - 4.0)) : 2.0 * d1;
  for (size_t r = 0; r < n_runs; ++r) {
    OperatingRun run;
    run.run_id = runs[r].meta("run_id").value_or("run " + std::to_string(r + 1));
    run.speed_rpm = data[r].skeleton.speed_rpm.value_or(plant.speed_rpm);
    run.log_factor.assign(fits[r].theta.data(), fits[r].theta.data() + k);
    run.values = static_cast<int>(n_ent * lines);
    for (size_t e = 0; e < n_ent; ++e) {
      const FrfEntry* fe = runs[r].find(first.entries[e].output, first.entries[e].input);
      for (size_t l = 0; l < lines; ++l) {
        run.chi2 += std::norm(data[r].h[e][l] - model_at[r][e][l] - bias[e][l]) / (fe->sigma[l] * fe->sigma[l]);
      }
    }
    ref.runs.push_back(run);
  }
  for (size_t e = 0; e < n_ent; ++e) {
    OperatingEntry oe;
    oe.output = first.entries[e].output;
    oe.input = first.entries[e].input;
    oe.bias = bias[e];
    oe.sigma2.assign(lines, 0.0);
    for (size_t r = 0; r < n_runs; ++r) {
      const FrfEntry* fe = runs[r].find(oe.output, oe.input);
      for (size_t l = 0; l < lines; ++l) oe.sigma2[l] += fe->sigma[l] * fe->sigma[l] / n;
    }
    double s = 0.0;
    for (size_t r = 0; r < n_runs; ++r)
      for (size_t l = 0; l < lines; ++l) s += 2.0 * std::norm(data[r].h[e][l] - model_at[r][e][l] - bias[e][l]) / oe.sigma2[l];
    // S as the scaled chi2 g chi2_h with its mean and variance.
    const double mean_s = line_mean * static_cast<double>(lines), var_s = line_var * static_cast<double>(lines);
    const double g = var_s / (2.0 * mean_s), h = 2.0 * mean_s * mean_s / var_s;
    oe.scatter_ratio = s / mean_s;
    oe.scatter_p = chi2_sf(s / g, h);
    if (oe.scatter_p < options.alpha_scatter) oe.kappa = oe.scatter_ratio;
    ref.entries.push_back(std::move(oe));
  }
  return ref;
}

}  // namespace ambdiag
