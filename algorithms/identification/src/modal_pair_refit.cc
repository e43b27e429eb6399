// Maximum-likelihood refit of two close poles with modal (rank-one)
// residues, the other poles fixed and their residues projected out.
#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <cmath>

#include "fit_data.h"

namespace ambdiag::detail {

namespace {

// Real 2-vector of the complex product a x, as a 2 x 2 matrix acting on
// (Re x, Im x).
Eigen::Matrix2d times(cd a) {
  Eigen::Matrix2d m;
  m << a.real(), -a.imag(), a.imag(), a.real();
  return m;
}

// The other poles' basis projected out, per entry (or once, with the
// entry's factor, when the weights are separable). For two poles the
// projected model of entry e is Z_e [0; r_e] with Z_e = P_e [U_e B_e] (2L x
// 8): B the weighted basis columns of the pair, U their derivatives (u1 =
// g + gc, u2 = j (g - gc) per pole). All that LM needs of entry e is
// K_e = Z_e^T Z_e, g_e = Z_e^T y_e (y projected) and c_e = |y_e|^2.
struct Problem {
  const FitData& data;
  const ModalStructure& modal;
  bool separable = false;
  Eigen::VectorXd wa, wb;
  std::vector<GramSolver> gram;  // per entry, or one (separable)
  std::vector<Eigen::MatrixXd> a;
  Eigen::MatrixXd y_perp;        // 2L x entries, projected (separable: without b(e))
  Eigen::VectorXd c;             // |y_perp|^2 per entry (weighted)
  // General weights: the other poles' basis and its per-entry least squares
  // (Gram factorizations; weighted residual = -projected weighted data).
  Eigen::MatrixXcd phi;
  EntrySystems sys;

  Eigen::MatrixXd project(size_t k, const Eigen::MatrixXd& v) const { return v - a[k] * gram[k].solve(a[k].transpose() * v); }
};

struct Blocks {
  std::vector<Eigen::Matrix<double, 8, 8>> k;
  std::vector<Eigen::Matrix<double, 8, 1>> g;
};

Blocks blocks(const Problem& pr, cd q0, cd q1) {
  const FitData& d = pr.data;
  const int L = d.lines(), E = d.entries();
  Eigen::MatrixXcd ub(L, 8);
  ub.rightCols(4) = pole_basis({q0, q1}, d.w, false);
  const cd j(0.0, 1.0), q[2] = {q0, q1};
  for (int l = 0; l < L; ++l) {
    const cd s(0.0, d.w(l));
    for (int m = 0; m < 2; ++m) {
      const cd g = 1.0 / ((s - q[m]) * (s - q[m])), gc = 1.0 / ((s - std::conj(q[m])) * (s - std::conj(q[m])));
      ub(l, 2 * m) = g + gc;
      ub(l, 2 * m + 1) = j * (g - gc);
    }
  }
  Blocks out;
  if (pr.separable) {
    const Eigen::MatrixXd z = pr.project(0, stack_lines(ub, pr.wa));
    const Eigen::Matrix<double, 8, 8> k0 = z.transpose() * z;
    const Eigen::MatrixXd g0 = z.transpose() * pr.y_perp;
    for (int e = 0; e < E; ++e) {
      const double b2 = pr.wb(e) * pr.wb(e);
      out.k.push_back(b2 * k0);
      out.g.push_back(b2 * g0.col(e));
    }
    return out;
  }
  // General weights: Z_e^T Z_e = S_xx - S_px^T G_e^-1 S_px from the
  // weighted Gram matrices of [phi ub] (entry_grams), Z_e^T y_e =
  // Re(ub^H w_e y_perp_e), without forming Z_e.
  const int nc = static_cast<int>(pr.phi.cols());
  Eigen::MatrixXcd basis(L, nc + 8);
  basis << pr.phi, ub;
  const Eigen::MatrixXd grams = entry_grams(basis, d.weight.cwiseAbs2(), nc);
  const Eigen::MatrixXd wy_r = -d.weight.cwiseProduct(pr.sys.wresid.real()), wy_i = -d.weight.cwiseProduct(pr.sys.wresid.imag());
  const Eigen::MatrixXd gy = ub.real().transpose() * wy_r + ub.imag().transpose() * wy_i;
  for (int e = 0; e < E; ++e) {
    const Eigen::MatrixXd sg = unpack_gram(grams.row(e).transpose(), nc + 8, nc);
    const Eigen::MatrixXd spx = sg.topRightCorner(nc, 8);
    out.k.push_back(sg.bottomRightCorner(8, 8) - spx.transpose() * pr.sys.gram[static_cast<size_t>(e)].solve(spx));
    out.g.push_back(gy.col(e));
  }
  return out;
}

// Parameters: [Re q1, Im q1, Re q2, Im q2, (Re, Im) psi(o, m) for o, m,
// (Re, Im) l(i, m) for i, m]; the residue of pole m in entry (o, i) is
// psi(o, m) l(i, m).
struct Params {
  cd q[2];
  Eigen::MatrixXcd psi, l;  // outputs x 2, inputs x 2
};

int count(const ModalStructure& s) { return 4 + 4 * s.outputs + 4 * s.inputs; }

Params apply(const Params& p, const Eigen::VectorXd& step, const ModalStructure& s) {
  Params out = p;
  for (int m = 0; m < 2; ++m) out.q[m] += cd(step(2 * m), step(2 * m + 1));
  int k = 4;
  for (int o = 0; o < s.outputs; ++o)
    for (int m = 0; m < 2; ++m, k += 2) out.psi(o, m) += cd(step(k), step(k + 1));
  for (int i = 0; i < s.inputs; ++i)
    for (int m = 0; m < 2; ++m, k += 2) out.l(i, m) += cd(step(k), step(k + 1));
  return out;
}

// Weighted cost at p; with jtj, jtr the Gauss-Newton system. The entry's
// Jacobian is Z_e S_e, S_e (8 x parameters) mapping the parameters to the
// pole derivatives (rows 0-3: the residue times the derivative basis) and to
// the residue coefficients (rows 4-7: r = psi l, linear in each).
double evaluate(const Problem& pr, const Params& p, Eigen::MatrixXd* jtj, Eigen::VectorXd* jtr) {
  const ModalStructure& s = pr.modal;
  const int E = pr.data.entries(), n = count(s);
  const Blocks bl = blocks(pr, p.q[0], p.q[1]);
  if (jtj) {
    *jtj = Eigen::MatrixXd::Zero(n, n);
    *jtr = Eigen::VectorXd::Zero(n);
  }
  double cost = 0.0;
  Eigen::MatrixXd sm(8, n);
  for (int e = 0; e < E; ++e) {
    const int o = s.output_of[static_cast<size_t>(e)], i = s.input_of[static_cast<size_t>(e)];
    Eigen::Matrix<double, 8, 1> x = Eigen::Matrix<double, 8, 1>::Zero();
    cd res[2];
    for (int m = 0; m < 2; ++m) {
      res[m] = p.psi(o, m) * p.l(i, m);
      x(4 + 2 * m) = res[m].real();
      x(4 + 2 * m + 1) = res[m].imag();
    }
    const Eigen::Matrix<double, 8, 8>& k = bl.k[static_cast<size_t>(e)];
    const Eigen::Matrix<double, 8, 1>& g = bl.g[static_cast<size_t>(e)];
    cost += x.dot(k * x) - 2.0 * x.dot(g) + pr.c(e);
    if (!jtj) continue;
    sm.setZero();
    for (int m = 0; m < 2; ++m) {
      sm.block(2 * m, 2 * m, 2, 2) = times(res[m]);
      sm.block(4 + 2 * m, 4 + 4 * o + 2 * m, 2, 2) = times(p.l(i, m));
      sm.block(4 + 2 * m, 4 + 4 * s.outputs + 4 * i + 2 * m, 2, 2) = times(p.psi(o, m));
    }
    jtj->noalias() += sm.transpose() * k * sm;
    jtr->noalias() += sm.transpose() * (k * x - g);
  }
  return cost;
}

}  // namespace

PairRefit refit_pair_rank_one(const FitData& data, const std::vector<cd>& poles, const Eigen::MatrixXcd& residues, size_t k1, size_t k2,
                              const ModalStructure& modal, int max_iterations) {
  PairRefit out;
  const int E = data.entries(), L = data.lines();
  std::vector<cd> others;
  for (size_t k = 0; k < poles.size(); ++k)
    if (k != k1 && k != k2) others.push_back(poles[k]);
  const Eigen::MatrixXcd phi = pole_basis(others, data.w, true);
  Problem pr{data, modal, false, {}, {}, {}, {}, {}, {}, {}, {}};
  pr.separable = separable_weights(data, pr.wa, pr.wb);
  pr.y_perp.resize(2 * L, E);
  pr.c.resize(E);
  if (pr.separable) {
    pr.a.push_back(stack_lines(phi, pr.wa));
    pr.gram.emplace_back(pr.a[0]);
    pr.y_perp = pr.project(0, stack_lines(data.h, pr.wa));
    for (int e = 0; e < E; ++e) pr.c(e) = pr.wb(e) * pr.wb(e) * pr.y_perp.col(e).squaredNorm();
  } else {
    pr.phi = phi;
    pr.sys = solve_entries(data, phi);
    pr.c = pr.sys.wresid.colwise().squaredNorm().transpose();
  }
  // Start: the best rank-one approximation of each pole's free residue
  // matrix (entries not fitted count as 0), split evenly between psi and l.
  Params p;
  p.q[0] = poles[k1];
  p.q[1] = poles[k2];
  p.psi = Eigen::MatrixXcd::Zero(modal.outputs, 2);
  p.l = Eigen::MatrixXcd::Zero(modal.inputs, 2);
  for (int m = 0; m < 2; ++m) {
    Eigen::MatrixXcd r = Eigen::MatrixXcd::Zero(modal.outputs, modal.inputs);
    for (int e = 0; e < E; ++e) r(modal.output_of[static_cast<size_t>(e)], modal.input_of[static_cast<size_t>(e)]) = residues(e, static_cast<Eigen::Index>(m == 0 ? k1 : k2));
    Eigen::JacobiSVD<Eigen::MatrixXcd> svd(r, Eigen::ComputeThinU | Eigen::ComputeThinV);
    const double s0 = std::sqrt(svd.singularValues()(0));
    p.psi.col(m) = s0 * svd.matrixU().col(0);
    p.l.col(m) = s0 * svd.matrixV().col(0).conjugate();
  }
  Eigen::MatrixXd jtj;
  Eigen::VectorXd jtr;
  double cost = evaluate(pr, p, &jtj, &jtr), mu = 1e-3;
  const double n_real = 2.0 * L * E;
  for (int it = 0; it < max_iterations; ++it) {
    bool accepted = false, done = false;
    for (int tries = 0; tries < 12 && !accepted; ++tries) {
      Eigen::MatrixXd lhs = jtj;
      lhs.diagonal() += mu * jtj.diagonal().cwiseMax(1e-12 * jtj.diagonal().maxCoeff());
      const Eigen::VectorXd step = -lhs.ldlt().solve(jtr);
      const Params trial = apply(p, step, modal);
      if (step.allFinite() && trial.q[0].real() < 0 && trial.q[1].real() < 0 && trial.q[0].imag() > 0 && trial.q[1].imag() > 0) {
        const double tc = evaluate(pr, trial, nullptr, nullptr);
        if (tc < cost) {
          done = (cost - tc) * n_real / cost < 1e-3;  // chi^2 drop below 1e-3, as in ml_refine
          p = trial;
          cost = evaluate(pr, p, &jtj, &jtr);
          mu = std::max(mu / 3.0, 1e-12);
          accepted = true;
          continue;
        }
      }
      mu *= 4.0;
    }
    out.iterations = it + 1;
    if (!accepted || done) break;
  }
  out.poles[0] = p.q[0];
  out.poles[1] = p.q[1];
  out.cost = cost;
  out.residues.resize(E, 2);
  for (int e = 0; e < E; ++e)
    for (int m = 0; m < 2; ++m) out.residues(e, m) = p.psi(modal.output_of[static_cast<size_t>(e)], m) * p.l(modal.input_of[static_cast<size_t>(e)], m);
  // Marginal covariance of the pole parameters: the Schur complement of
  // the residue block (singular: psi and l share one complex scale per
  // pole, so its pseudo-inverse).
  const int nr = static_cast<int>(jtj.rows()) - 4;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(jtj.bottomRightCorner(nr, nr));
  const Eigen::VectorXd ev = es.eigenvalues();
  Eigen::VectorXd inv = Eigen::VectorXd::Zero(nr);
  for (int k = 0; k < nr; ++k)
    if (ev(k) > 1e-10 * ev.maxCoeff()) inv(k) = 1.0 / ev(k);
  const Eigen::MatrixXd cross = jtj.topRightCorner(4, nr) * es.eigenvectors();
  const Eigen::Matrix4d info = jtj.topLeftCorner(4, 4) - cross * inv.asDiagonal() * cross.transpose();
  out.covariance = info.inverse();
  out.ok = out.covariance.allFinite() && out.covariance(0, 0) > 0 && out.covariance(2, 2) > 0;
  return out;
}

}  // namespace ambdiag::detail
