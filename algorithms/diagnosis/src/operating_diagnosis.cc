// Diagnosis of a run that the operating reference detected: every fault
// hypothesis at the run's speed with the seal drift profiled out, the best
// ones fitted jointly with the drift (operating_reference.h).
#include <Eigen/Cholesky>
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "frf_fit_target.h"
#include "operating_internal.h"

namespace ambdiag::operating_detail {

using diagnosis_detail::Aligned;

namespace {

// The best candidates again with the nuisance fitted jointly and exactly
// (no linearisation): the fault's parameter and theta by Levenberg-Marquardt
// on the data plus the prior rows. A seal fault and its link's drift are
// the same change of the model, so only the prior separates them; the
// linearised profile (Jacobian at the healthy state) is not degenerate in
// them and would let the data decide the split (1.282 for 1.300 once, and
// a chi2 lower than the exact model's by 5). The exact fit replaces the
// profile's values.
void refine_jointly(FaultEstimate& est, const PlantModel& plant, const std::vector<int>& links, const RunData& run,
                    const FrfFitTarget& target, const Eigen::VectorXd& theta_mean, const Eigen::MatrixXd& u_prior, double bound,
                    const Aligned& a, int& evaluations) {
  const FaultHypothesis& h = est.hypothesis;
  const Eigen::Index k = theta_mean.size();
  auto model = [&](const std::vector<double>& xv) {
    const Eigen::Map<const Eigen::VectorXd> x(xv.data(), static_cast<Eigen::Index>(xv.size()));
    ++evaluations;
    Values v = model_values(apply_fault(with_nuisance(plant, links, x.tail(k)), h, x[0]), run.skeleton);
    const Eigen::VectorXd z = u_prior * (x.tail(k) - theta_mean);
    std::vector<std::complex<double>> prior_row;
    for (Eigen::Index i = 0; i < k; ++i) prior_row.emplace_back(z[i], 0.0);
    v.push_back(std::move(prior_row));
    return v;
  };
  std::vector<FitParameter> params{{h.parameter, est.value, h.lower, h.upper}};
  for (Eigen::Index i = 0; i < k; ++i) params.push_back({"log_factor", theta_mean[i], -bound, bound});
  LeastSquaresOptions o = secant_fit_options(15, 1e-9, 1e-7);
  o.fd_step = 1e-3;
  const LeastSquaresResult r = fit_parameters(model, target, params, o);
  est.value = r.x[0];
  est.sd = r.covariance(0, 0) > 0.0 ? std::sqrt(r.covariance(0, 0)) : std::numeric_limits<double>::infinity();
  est.chi2 = r.chi2;
  est.coefficient_factor = link_coefficient_factor(h, est.value);
  est.nrmse = diagnosis_detail::nrmse_of(model(r.x), a);
}

// A channel gain fitted jointly with the drift, linearised: the gain was
// solved on the prediction with the drift fitted to the faulty run, which
// took up part of the gain's change (a sensor at gain 0.8 came out 0.8012
// with sd 0.0003 in the fleet test, its interval missing the truth); here
// gain g and a drift step delta minimise
//   sum w^2 |s(g) (m + J delta) - h|^2 + |U (theta + delta - theta_mean)|^2
// (s(g) = g on the channel's row or column, 1 elsewhere; m the prediction at
// the fitted theta, J the nuisance Jacobian, U the prior's root), by
// Gauss-Newton: a few passes over the data, no model FRF. The interval then
// holds the drift's share (Cov = (J^T J)^-1 / 2, inflated by chi2 / N as
// the closed form's).
void refine_channel_jointly(FaultEstimate& est, const Aligned& a, const RunData& run, const NuisanceFit& nf,
                            const Eigen::VectorXd& theta_mean, const Eigen::MatrixXd& u_prior) {
  const FaultHypothesis& h = est.hypothesis;
  const bool row = h.kind == FaultKind::sensor_fault;
  const Eigen::Index k = theta_mean.size();
  const size_t n_ent = a.entries.size(), lines = a.freq_hz.size();
  std::vector<bool> on(n_ent);
  for (size_t e = 0; e < n_ent; ++e) on[e] = (row ? a.entries[e].output : a.entries[e].input) == h.channel;
  const Eigen::VectorXd d0 = nf.theta - theta_mean;
  // chi2 and, when wanted, the normal equations at (g, delta).
  auto evaluate = [&](double g, const Eigen::VectorXd& delta, Eigen::MatrixXd* jtj, Eigen::VectorXd* jtr) {
    if (jtj) *jtj = Eigen::MatrixXd::Zero(k + 1, k + 1), *jtr = Eigen::VectorXd::Zero(k + 1);
    double chi2 = 0.0;
    std::vector<std::complex<double>> col(static_cast<size_t>(k + 1));
    for (size_t e = 0; e < n_ent; ++e) {
      const double s = on[e] ? g : 1.0;
      for (size_t l = 0; l < lines; ++l) {
        std::complex<double> base = a.entries[e].mean[l];
        for (Eigen::Index i = 0; i < k; ++i) base += nf.jacobian[static_cast<size_t>(i)][e][l] * delta[i];
        const double w = run.weight[e][l];
        const std::complex<double> r = w * (s * base - a.entries[e].h[l]);
        chi2 += std::norm(r);
        if (!jtj) continue;
        col[0] = on[e] ? w * base : std::complex<double>(0.0, 0.0);
        for (Eigen::Index i = 0; i < k; ++i) col[static_cast<size_t>(i + 1)] = w * s * nf.jacobian[static_cast<size_t>(i)][e][l];
        for (Eigen::Index i = 0; i <= k; ++i) {
          (*jtr)[i] += (std::conj(col[static_cast<size_t>(i)]) * r).real();
          for (Eigen::Index j = 0; j <= k; ++j)
            (*jtj)(i, j) += (std::conj(col[static_cast<size_t>(i)]) * col[static_cast<size_t>(j)]).real();
        }
      }
    }
    const Eigen::VectorXd z = u_prior * (d0 + delta);
    chi2 += z.squaredNorm();
    if (jtj) {
      jtj->bottomRightCorner(k, k) += u_prior.transpose() * u_prior;
      jtr->tail(k) += u_prior.transpose() * z;
    }
    return chi2;
  };
  double g = est.value;
  Eigen::VectorXd delta = Eigen::VectorXd::Zero(k);
  double chi2 = evaluate(g, delta, nullptr, nullptr);
  Eigen::MatrixXd jtj;
  Eigen::VectorXd jtr;
  for (int pass = 0; pass < 6; ++pass) {
    evaluate(g, delta, &jtj, &jtr);
    const Eigen::VectorXd step = -jtj.ldlt().solve(jtr);
    const double g1 = std::clamp(g + step[0], h.lower, h.upper);
    const Eigen::VectorXd delta1 = delta + step.tail(k);
    const double chi2_1 = evaluate(g1, delta1, nullptr, nullptr);
    if (!(chi2_1 < chi2)) break;  // converged (or no better: keep the last)
    const bool small = std::fabs(g1 - g) < 1e-9 * std::max(1.0, std::fabs(g));
    g = g1, delta = delta1, chi2 = chi2_1;
    if (small) break;
  }
  evaluate(g, delta, &jtj, &jtr);
  const double n_values = static_cast<double>(a.values());
  const Eigen::MatrixXd cov = jtj.inverse() * 0.5 * std::max(1.0, chi2 / n_values);
  est.value = g;
  est.chi2 = chi2;
  est.sd = cov(0, 0) > 0.0 ? std::sqrt(cov(0, 0)) : std::numeric_limits<double>::infinity();
}

}  // namespace

int diagnose_faults(const PlantModel& plant, const std::vector<int>& links, const OperatingReference& ref, const Aligned& a,
                    const RunData& run, const NuisanceFit& nf, const DiagnosisOptions& options, DiagnosisResult& res) {
  auto progress = [&](const std::string& stage, int done, int total) {
    if (options.progress) options.progress(stage, done, total);
  };
  const Eigen::Index k = static_cast<Eigen::Index>(links.size());
  const size_t lines = a.freq_hz.size();
  Eigen::VectorXd theta_mean = Eigen::VectorXd::Zero(k);
  for (Eigen::Index i = 0; i < k; ++i) theta_mean[i] = ref.log_factor_mean[static_cast<size_t>(i)];
  const FrfFitTarget plain{a.freq_hz, run.h, run.weight, {}};

  // Diagnosis. Every fault hypothesis is evaluated at theta_mean and the
  // nuisance profiled out, linearised (Jacobian there, from the fit above):
  // min over delta of |r + J delta|^2 + delta^T P delta, P =
  // Sigma^-1 / 2 (the prior of the normal spread in complex-chi2 units), so
  // the drift may take its normal share of a change and no more; the prior
  // term is appended as K extra rows so that every fit sees it.
  const size_t n_ent = a.entries.size();
  Eigen::MatrixXd jtj = Eigen::MatrixXd::Zero(k, k), p_prior = Eigen::MatrixXd::Zero(k, k), u_prior = Eigen::MatrixXd::Zero(k, k);
  if (k > 0) {
    for (Eigen::Index i = 0; i < k; ++i)
      for (Eigen::Index j = 0; j < k; ++j) {
        double s = 0.0;
        for (size_t e = 0; e < n_ent; ++e)
          for (size_t l = 0; l < lines; ++l)
            s += run.weight[e][l] * run.weight[e][l] *
                 (std::conj(nf.jacobian[static_cast<size_t>(i)][e][l]) * nf.jacobian[static_cast<size_t>(j)][e][l]).real();
        jtj(i, j) = s;
      }
    p_prior = 0.5 * drift_covariance(ref, Eigen::MatrixXd()).inverse();
    u_prior = Eigen::LLT<Eigen::MatrixXd>(p_prior).matrixU();
  }
  const Eigen::MatrixXd solve_m = jtj + p_prior;
  auto profile = [&](Values& v) {
    if (k == 0) return;
    Eigen::VectorXd g = Eigen::VectorXd::Zero(k);
    for (size_t e = 0; e < n_ent; ++e)
      for (size_t l = 0; l < lines; ++l) {
        const std::complex<double> r = v[e][l] + run.offset[e][l] - run.h[e][l];
        const double w2 = run.weight[e][l] * run.weight[e][l];
        for (Eigen::Index i = 0; i < k; ++i) g[i] += w2 * (std::conj(nf.jacobian[static_cast<size_t>(i)][e][l]) * r).real();
      }
    const Eigen::VectorXd delta = -solve_m.ldlt().solve(g);
    for (size_t e = 0; e < n_ent; ++e)
      for (size_t l = 0; l < lines; ++l)
        for (Eigen::Index i = 0; i < k; ++i) v[e][l] += nf.jacobian[static_cast<size_t>(i)][e][l] * delta[i];
    const Eigen::VectorXd z = u_prior * delta;
    std::vector<std::complex<double>> prior_row;
    for (Eigen::Index i = 0; i < k; ++i) prior_row.emplace_back(z[i], 0.0);
    v.push_back(std::move(prior_row));
  };
  progress("nominal model", 0, 1);
  const PlantModel reference_state = k > 0 ? with_nuisance(plant, links, theta_mean) : plant;
  diagnosis_detail::ModelGrid grid(reference_state, a, profile);
  FrfFitTarget target{a.freq_hz, run.h, run.weight, run.offset};
  if (k > 0) {
    target.measured.emplace_back(static_cast<size_t>(k), std::complex<double>(0.0, 0.0));
    target.weight.emplace_back(static_cast<size_t>(k), 1.0);
    target.offset.emplace_back(static_cast<size_t>(k), std::complex<double>(0.0, 0.0));
  }
  // The healthy machine with its drift profiled: what the faults must beat.
  res.chi2_before = fit_chi2(target, grid.nominal());

  const std::vector<FaultHypothesis> hyps = fault_hypotheses(plant);
  std::vector<diagnosis_detail::Screened> screened;
  std::vector<FaultEstimate> cands = diagnosis_detail::fit_plant_faults(plant, hyps, grid, target, a, options, screened);
  int joint_evaluations = 0;
  if (k > 0 && !cands.empty()) {
    std::sort(cands.begin(), cands.end(), [](const FaultEstimate& x, const FaultEstimate& y) { return x.chi2 < y.chi2; });
    const size_t joint = std::min<size_t>(3, cands.size());
    for (size_t i = 0; i < joint; ++i) {
      progress("fitting fault and drift jointly", static_cast<int>(i), static_cast<int>(joint));
      refine_jointly(cands[i], plant, links, run, target, theta_mean, u_prior, ref.options.log_factor_bound, a, joint_evaluations);
    }
  }
  progress("channel faults", 0, 1);
  // Channel gains on the healthy prediction with the drift fitted (a.mean),
  // plus the prior penalty of that drift.
  const Eigen::VectorXd dn = k > 0 ? Eigen::VectorXd(nf.theta - theta_mean) : Eigen::VectorXd();
  const double drift_penalty = k > 0 ? dn.dot(p_prior * dn) : 0.0;
  std::vector<FaultEstimate> channels = diagnosis_detail::fit_channel_faults(plant, hyps, a, nf.at_theta, plain, drift_penalty);
  if (k > 0)
    for (auto& c : channels) refine_channel_jointly(c, a, run, nf, theta_mean, u_prior);
  cands.insert(cands.end(), channels.begin(), channels.end());
  diagnosis_detail::rank_faults(std::move(cands), hyps, screened, grid, a, options, res);
  progress("done", 1, 1);
  return grid.evaluations() + joint_evaluations;
}

}  // namespace ambdiag::operating_detail
