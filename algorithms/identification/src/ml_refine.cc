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

// Separable weights, weight(l, e) = a(l) b(e) (see separable_weights): the
// derivative of entry e's weighted model with respect to the pole
// parameters is D_e = b(e) Psi T_e, where Psi holds the derivatives of the
// basis functions (for a pair u1 = g + gc, u2 = j (g - gc), g = 1/(s-p)^2,
// gc = 1/(s-conj p)^2; for a real pole g), weighted by a(l), and T_e is
// block diagonal in the residue coefficients c1 + j c2 of the pole:
// d/dRe p = c1 u1 + c2 u2, d/dIm p = -c2 u1 + c1 u2. With A = b(e) A0 the
// basis, Kaufman's J^T J = D^T D - (A^T D)^T (A^T A)^-1 A^T D becomes
// b(e)^2 T_e^T K T_e with one K = Psi^T Psi - P^T (A0^T A0)^-1 P,
// P = A0^T Psi, for all entries: O(lines poles^2) once, O(poles^3) per entry
// instead of O(lines poles^2) per entry.
Normal normal_equations_separable(const FitData& data, const std::vector<cd>& poles, bool delay, const Eigen::VectorXd& wa,
                                  const Eigen::VectorXd& wb) {
  const int L = data.lines(), E = data.entries();
  const int npp = parameter_count(poles);
  const int np = npp + (delay ? 1 : 0);
  const Eigen::MatrixXcd phi = pole_basis(poles, data.w, true);
  const int nc = static_cast<int>(phi.cols());
  const Eigen::MatrixXcd u = derivative_basis(poles, data.w);
  const cd j(0.0, 1.0);
  const Eigen::MatrixXd a0 = stack_lines(phi, wa), psi = stack_lines(u, wa), y0 = stack_lines(data.h, wa);
  const GramSolver gram(a0);
  const Eigen::MatrixXd c = gram.solve(a0.transpose() * y0);
  const Eigen::MatrixXd r0 = a0 * c - y0;
  const Eigen::MatrixXd p = a0.transpose() * psi;
  const Eigen::MatrixXd k = psi.transpose() * psi - p.transpose() * gram.solve(p);
  const Eigen::MatrixXd psi_r = psi.transpose() * r0;
  // Delay column: d resid / d tau = -b(e) stack(a j w h).
  Eigen::MatrixXd v0, psi_v, z, a_v;
  if (delay) {
    Eigen::MatrixXcd jwh(L, E);
    for (int l = 0; l < L; ++l) jwh.row(l) = -(j * data.w(l)) * data.h.row(l);
    v0 = stack_lines(jwh, wa);
    a_v = a0.transpose() * v0;
    z = gram.solve(a_v);
    psi_v = psi.transpose() * v0 - p.transpose() * z;
  }
  Normal out;
  out.jtj = Eigen::MatrixXd::Zero(np, np);
  out.jtr = Eigen::VectorXd::Zero(np);
  out.linear.residues.resize(E, static_cast<Eigen::Index>(poles.size()));
  out.linear.direct.resize(E);
  out.linear.cost = (r0 * wb.asDiagonal()).squaredNorm();
  Eigen::MatrixXd t = Eigen::MatrixXd::Zero(npp, npp);
  for (int e = 0; e < E; ++e) {
    const auto r = residues_from_coefficients(poles, c.col(e));
    for (size_t q = 0; q < r.size(); ++q) out.linear.residues(e, static_cast<Eigen::Index>(q)) = r[q];
    out.linear.direct(e) = c(nc - 1, e);
    int col = 0;
    for (size_t q = 0; q < poles.size(); ++q) {
      if (poles[q].imag() == 0.0) {
        t(col, col) = r[q].real();
        ++col;
      } else {
        t(col, col) = r[q].real();
        t(col + 1, col) = r[q].imag();
        t(col, col + 1) = -r[q].imag();
        t(col + 1, col + 1) = r[q].real();
        col += 2;
      }
    }
    const double b2 = wb(e) * wb(e);
    out.jtj.topLeftCorner(npp, npp).noalias() += b2 * (t.transpose() * k * t);
    out.jtr.head(npp).noalias() += b2 * (t.transpose() * psi_r.col(e));
    if (delay) {
      const Eigen::VectorXd pd = b2 * (t.transpose() * psi_v.col(e));
      out.jtj.block(0, npp, npp, 1) += pd;
      out.jtj.block(npp, 0, 1, npp) += pd.transpose();
      out.jtj(npp, npp) += b2 * (v0.col(e).squaredNorm() - a_v.col(e).dot(z.col(e)));
      out.jtr(npp) += b2 * v0.col(e).dot(r0.col(e));
    }
  }
  return out;
}

// Block-diagonal map T_e from the pole derivatives of the basis functions to
// those of entry e's model (see normal_equations_separable).
Eigen::MatrixXd residue_map(const std::vector<cd>& poles, const std::vector<cd>& r, int npp) {
  Eigen::MatrixXd t = Eigen::MatrixXd::Zero(npp, npp);
  int col = 0;
  for (size_t q = 0; q < poles.size(); ++q) {
    t(col, col) = r[q].real();
    if (poles[q].imag() == 0.0) {
      ++col;
    } else {
      t(col + 1, col) = r[q].imag();
      t(col, col + 1) = -r[q].imag();
      t(col + 1, col + 1) = r[q].real();
      col += 2;
    }
  }
  return t;
}

// General weights (one per line and entry). The residual, the residues and
// the gradient J^T r = D^T r (A^T r = 0) come from the per-entry least
// squares `sys` (of the accepted LM trial, not solved again). Kaufman's J^T
// J of entry e is T_e^T K_e T_e, K_e = S_uu - S_pu^T G_e^-1 S_pu, from the
// weighted Gram matrices of the pole basis phi (G_e, in `sys`) and of its
// derivatives u (S_pu, S_uu; entry_grams: one blocked product for all
// entries, half the flops of the stacked per-entry products).
Normal normal_equations_general(const FitData& data, const std::vector<cd>& poles, bool delay, const Eigen::MatrixXcd& phi,
                                const EntrySystems& sys) {
  const int L = data.lines(), E = data.entries();
  const int npp = parameter_count(poles);
  const int np = npp + (delay ? 1 : 0);
  const int nc = static_cast<int>(phi.cols()), nb = nc + npp;
  const Eigen::MatrixXcd u = derivative_basis(poles, data.w);
  const Eigen::MatrixXd w2 = data.weight.cwiseAbs2();
  Eigen::MatrixXcd basis(L, nb);
  basis << phi, u;
  const Eigen::MatrixXd grams = entry_grams(basis, w2, nc);  // S_pu and S_uu; G_e is in sys
  const Eigen::MatrixXd ur = u.real(), ui = u.imag();
  const Eigen::MatrixXd grad = ur.transpose() * data.weight.cwiseProduct(sys.wresid.real()) + ui.transpose() * data.weight.cwiseProduct(sys.wresid.imag());
  // Delay column v_e = -w_e .* (j w h_e), exact (data, not a common basis).
  Eigen::MatrixXd av, dv;
  Eigen::VectorXd vv, vr;
  if (delay) {
    Eigen::MatrixXcd w2jwh(L, E);
    for (int l = 0; l < L; ++l) w2jwh.row(l) = cd(0.0, data.w(l)) * data.h.row(l);
    const Eigen::MatrixXcd wjwh = data.weight.cast<cd>().cwiseProduct(w2jwh);
    vv = wjwh.colwise().squaredNorm().transpose();
    vr = -(wjwh.conjugate().cwiseProduct(sys.wresid)).colwise().sum().real().transpose();
    w2jwh = w2.cast<cd>().cwiseProduct(w2jwh);
    av = -(phi.adjoint() * w2jwh).real();
    dv = -(u.adjoint() * w2jwh).real();
  }
  Normal out;
  out.jtj = Eigen::MatrixXd::Zero(np, np);
  out.jtr = Eigen::VectorXd::Zero(np);
  out.linear.residues.resize(E, static_cast<Eigen::Index>(poles.size()));
  out.linear.direct.resize(E);
  out.linear.cost = sys.cost;
  for (int e = 0; e < E; ++e) {
    const auto r = residues_from_coefficients(poles, sys.coef.col(e));
    for (size_t q = 0; q < r.size(); ++q) out.linear.residues(e, static_cast<Eigen::Index>(q)) = r[q];
    out.linear.direct(e) = sys.coef(nc - 1, e);
    const GramSolver& gram = sys.gram[static_cast<size_t>(e)];
    const Eigen::MatrixXd s = unpack_gram(grams.row(e).transpose(), nb, nc);
    const Eigen::MatrixXd spu = s.topRightCorner(nc, npp);
    const Eigen::MatrixXd k = s.bottomRightCorner(npp, npp) - spu.transpose() * gram.solve(spu);
    const Eigen::MatrixXd t = residue_map(poles, r, npp);
    out.jtj.topLeftCorner(npp, npp).noalias() += t.transpose() * k * t;
    out.jtr.head(npp).noalias() += t.transpose() * grad.col(e);
    if (delay) {
      const Eigen::VectorXd z = gram.solve(av.col(e));
      const Eigen::VectorXd pd = t.transpose() * (dv.col(e) - spu.transpose() * z);
      out.jtj.block(0, npp, npp, 1) += pd;
      out.jtj.block(npp, 0, 1, npp) += pd.transpose();
      out.jtj(npp, npp) += vv(e) - av.col(e).dot(z);
      out.jtr(npp) += vr(e);
    }
  }
  return out;
}

// `data` is already undelayed; with `delay` one more column, d resid / d tau
// = -d y / d tau = -weighted(j w h). Exact J^T J.
Normal normal_equations(const FitData& data, const std::vector<cd>& poles, bool delay = false) {
  Eigen::VectorXd wa, wb;
  if (separable_weights(data, wa, wb)) return normal_equations_separable(data, poles, delay, wa, wb);
  const Eigen::MatrixXcd phi = pole_basis(poles, data.w, true);
  return normal_equations_general(data, poles, delay, phi, solve_entries(data, phi));
}

}  // namespace

MlSolution ml_refine(const FitData& data_in, std::vector<cd> poles, int max_iterations, bool fit_delay, double delay_s,
                     const std::vector<bool>& fixed) {
  MlSolution out;
  // Parameters of fixed poles: their rows and columns of J^T J are replaced
  // by the identity and their gradient by 0, so no step moves them.
  std::vector<int> fixed_params;
  for (size_t k = 0, c = 0; k < poles.size(); ++k) {
    const int n = poles[k].imag() == 0.0 ? 1 : 2;
    if (k < fixed.size() && fixed[k])
      for (int i = 0; i < n; ++i) fixed_params.push_back(static_cast<int>(c) + i);
    c += static_cast<size_t>(n);
  }
  const auto hold = [&fixed_params](Eigen::MatrixXd& jtj, Eigen::VectorXd& jtr) {
    for (int i : fixed_params) {
      jtj.row(i).setZero();
      jtj.col(i).setZero();
      jtj(i, i) = 1.0;
      jtr(i) = 0.0;
    }
  };
  double mu = 1e-3;
  FitData data = undelayed(data_in, delay_s);
  // General weights: the least squares of the accepted trial are kept.
  Eigen::VectorXd wa, wb;
  const bool separable = separable_weights(data, wa, wb);
  EntrySystems current;
  auto build = [&](const std::vector<cd>& p) {
    if (separable) return normal_equations_separable(data, p, fit_delay, wa, wb);
    const Eigen::MatrixXcd phi = pole_basis(p, data.w, true);
    if (current.gram.empty()) current = solve_entries(data, phi);
    return normal_equations_general(data, p, fit_delay, phi, current);
  };
  Normal ne = build(poles);
  hold(ne.jtj, ne.jtr);

  double cost = ne.linear.cost;
  const int npp = parameter_count(poles);
  // Converged when an accepted step lowers chi^2 (in units of the noise,
  // estimated as 2 cost / n) by less than 1e-3: the estimate is then within
  // a few hundredths of a standard deviation of the optimum. (A relative
  // 1e-10 took twice the iterations on real data, where LM crawls through a
  // flat valley of poorly determined poles with no gain in accuracy.)
  const double n_real = 2.0 * data.lines() * data.entries();
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
        EntrySystems sys;
        double trial_cost = 0.0;
        if (separable) {
          trial_cost = solve_residues(trial_data, trial).cost;
        } else {
          sys = solve_entries(trial_data, pole_basis(trial, trial_data.w, true));
          trial_cost = sys.cost;
        }
        if (trial_cost < cost) {
          const double chi2_drop = (cost - trial_cost) * n_real / std::max(cost, 1e-300);
          poles = trial;
          delay_s = trial_delay;
          data = std::move(trial_data);
          cost = trial_cost;
          mu = std::max(mu / 3.0, 1e-12);
          accepted = true;
          current = std::move(sys);
          ne = build(poles);
          hold(ne.jtj, ne.jtr);
          if (chi2_drop < 1e-3) {
            out.converged = true;
            out.stop_reason = "chi^2 decrease below 1e-3";
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
