// Maximum-likelihood refinement of the common poles: Levenberg-Marquardt on
// the weighted least-squares cost with the residues and direct terms
// projected out (variable projection; Golub & Pereyra 1973, Jacobian after
// Kaufman 1975). Optionally a pure delay e^{-j w tau} of the whole matrix
// (an acquisition delay) as one more nonlinear parameter.
#include <Eigen/Dense>
#include <cmath>
#include <limits>

#include "fit_data.h"

namespace ambdiag::detail {

namespace {

int parameter_count(const std::vector<cd>& poles) { return basis_columns(poles); }

std::vector<cd> apply_step(const std::vector<cd>& poles, const Eigen::VectorXd& step) {
  // A trailing delay parameter, if any, is not a pole and is ignored here.
  std::vector<cd> out;
  int k = 0;
  for (const cd& p : poles) {
    if (p.imag() == 0.0) {
      out.emplace_back(p.real() + step(k++), 0.0);
    } else {
      out.emplace_back(p.real() + step(k), std::abs(p.imag() + step(k + 1)));
      k += 2;
    }
  }
  return out;
}

bool stable(const std::vector<cd>& poles) {
  for (const cd& p : poles)
    if (!(p.real() < 0.0) || !std::isfinite(p.real()) || !std::isfinite(p.imag())) return false;
  return true;
}

// Gauss-Newton system of the projected problem at `poles`.
struct Normal {
  Eigen::MatrixXd jtj;
  Eigen::VectorXd jtr;
  LinearSolution linear;
};

// `data` is already undelayed; with `delay` one more column, d resid / d tau
// = -d y / d tau = -weighted(j w h).
Normal normal_equations(const FitData& data, const std::vector<cd>& poles, bool delay = false) {
  const int L = data.lines(), E = data.entries();
  const int npp = parameter_count(poles);
  const int np = npp + (delay ? 1 : 0);
  const Eigen::MatrixXcd phi = pole_basis(poles, data.w, true);
  const int nc = static_cast<int>(phi.cols());
  Normal out;
  out.jtj = Eigen::MatrixXd::Zero(np, np);
  out.jtr = Eigen::VectorXd::Zero(np);
  out.linear.residues.resize(E, static_cast<Eigen::Index>(poles.size()));
  out.linear.direct.resize(E);

  // 1/(s - p)^2 and 1/(s - conj p)^2 per line and pole.
  Eigen::MatrixXcd g(L, static_cast<Eigen::Index>(poles.size())), gc(L, static_cast<Eigen::Index>(poles.size()));
  for (int l = 0; l < L; ++l) {
    const cd s(0.0, data.w(l));
    for (size_t k = 0; k < poles.size(); ++k) {
      g(l, static_cast<Eigen::Index>(k)) = 1.0 / ((s - poles[k]) * (s - poles[k]));
      gc(l, static_cast<Eigen::Index>(k)) = 1.0 / ((s - std::conj(poles[k])) * (s - std::conj(poles[k])));
    }
  }
  Eigen::MatrixXd a, dmat(2 * L, np);
  Eigen::VectorXd y;
  const cd j(0.0, 1.0);
  for (int e = 0; e < E; ++e) {
    stack_weighted(data, phi, e, a, y);
    const GramSolver gram(a);
    const Eigen::VectorXd c = gram.solve(a.transpose() * y);
    const Eigen::VectorXd resid = a * c - y;
    out.linear.cost += resid.squaredNorm();
    const auto r = residues_from_coefficients(poles, c);
    for (size_t k = 0; k < r.size(); ++k) out.linear.residues(e, static_cast<Eigen::Index>(k)) = r[k];
    out.linear.direct(e) = c(nc - 1);

    // Derivatives of the weighted model with respect to Re p and Im p.
    for (int l = 0; l < L; ++l) {
      const double wt = data.weight(l, e);
      int col = 0;
      for (size_t k = 0; k < poles.size(); ++k) {
        const cd gk = g(l, static_cast<Eigen::Index>(k)), gck = gc(l, static_cast<Eigen::Index>(k));
        if (poles[k].imag() == 0.0) {
          const cd d = wt * r[k] * gk;
          dmat(l, col) = d.real();
          dmat(L + l, col) = d.imag();
          ++col;
        } else {
          const cd da = wt * (r[k] * gk + std::conj(r[k]) * gck);
          const cd db = wt * (j * r[k] * gk - j * std::conj(r[k]) * gck);
          dmat(l, col) = da.real();
          dmat(L + l, col) = da.imag();
          dmat(l, col + 1) = db.real();
          dmat(L + l, col + 1) = db.imag();
          col += 2;
        }
      }
      if (delay) {
        const cd dy = wt * j * data.w(l) * data.h(l, e);
        dmat(l, npp) = -dy.real();
        dmat(L + l, npp) = -dy.imag();
      }
    }
    // Kaufman: J = P_perp D, P_perp = I - A (A^T A)^-1 A^T, so
    // J^T J = D^T D - (A^T D)^T (A^T A)^-1 (A^T D).
    const Eigen::MatrixXd atd = a.transpose() * dmat;
    out.jtj.noalias() += dmat.transpose() * dmat - atd.transpose() * gram.solve(atd);
    out.jtr.noalias() += dmat.transpose() * resid;  // A^T resid = 0 at the LS solution
  }
  return out;
}

}  // namespace

MlSolution ml_refine(const FitData& data_in, std::vector<cd> poles, int max_iterations, bool fit_delay, double delay_s) {
  MlSolution out;
  double mu = 1e-3;
  FitData data = undelayed(data_in, delay_s);
  Normal ne = normal_equations(data, poles, fit_delay);
  double cost = ne.linear.cost;
  const int npp = parameter_count(poles);
  out.stop_reason = "iteration limit";
  int it = 0;
  for (; it < max_iterations; ++it) {
    bool accepted = false;
    for (int tries = 0; tries < 12 && !accepted; ++tries) {
      Eigen::MatrixXd lhs = ne.jtj;
      lhs.diagonal() += mu * ne.jtj.diagonal().cwiseMax(1e-300);
      const Eigen::VectorXd step = -lhs.ldlt().solve(ne.jtr);
      const std::vector<cd> trial = apply_step(poles, step);
      const double trial_delay = fit_delay ? delay_s + step(npp) : delay_s;
      if (stable(trial) && step.allFinite()) {
        FitData trial_data = fit_delay ? undelayed(data_in, trial_delay) : data;
        const LinearSolution lin = solve_residues(trial_data, trial);
        if (lin.cost < cost) {
          const double drop = (cost - lin.cost) / std::max(cost, 1e-300);
          poles = trial;
          delay_s = trial_delay;
          data = std::move(trial_data);
          cost = lin.cost;
          mu = std::max(mu / 3.0, 1e-12);
          accepted = true;
          ne = normal_equations(data, poles, fit_delay);
          if (drop < 1e-10) {
            out.converged = true;
            out.stop_reason = "relative cost decrease below 1e-10";
          }
          continue;
        }
      }
      mu *= 4.0;
    }
    if (!accepted) {
      out.converged = true;  // no step lowers the cost: a (local) minimum
      out.stop_reason = "no further decrease (local minimum)";
      break;
    }
    if (out.converged) {
      ++it;
      break;
    }
  }
  out.iterations = it;
  out.poles = poles;
  out.delay_s = delay_s;
  out.linear = ne.linear;
  // Marginal covariance of the poles (the delay's uncertainty included).
  const Eigen::MatrixXd cov = ne.jtj.ldlt().solve(Eigen::MatrixXd::Identity(ne.jtj.rows(), ne.jtj.cols()));
  out.pole_covariance = cov.topLeftCorner(npp, npp);
  if (fit_delay) out.delay_sd_s = std::sqrt(std::max(0.0, 0.5 * cov(npp, npp)));
  return out;
}

double delay_score(const FitData& data, const std::vector<cd>& poles, double delay_s) {
  const Normal ne = normal_equations(undelayed(data, delay_s), poles, true);
  const Eigen::VectorXd step = ne.jtj.ldlt().solve(ne.jtr);
  return 2.0 * ne.jtr.dot(step);
}

FitData undelayed(const FitData& data, double delay_s) {
  FitData out = data;
  if (delay_s == 0.0) return out;
  for (int l = 0; l < data.lines(); ++l) out.h.row(l) *= std::polar(1.0, data.w(l) * delay_s);
  return out;
}

}  // namespace ambdiag::detail
