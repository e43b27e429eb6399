#include <cmath>

#include <Eigen/Dense>

#include "fit_data.h"

namespace ambdiag::detail {

namespace {

// 1 / z without the library's complex division (which guards against
// overflow and infinities that a nonzero s - p never reaches): a third of
// the fit's basis evaluation time went there.
inline cd inverse(cd z) {
  const double n = z.real() * z.real() + z.imag() * z.imag();
  return cd(z.real() / n, -z.imag() / n);
}

}  // namespace

int basis_columns(const std::vector<cd>& poles) {
  int n = 0;
  for (const cd& p : poles) n += p.imag() == 0.0 ? 1 : 2;
  return n;
}

Eigen::MatrixXcd pole_basis(const std::vector<cd>& poles, const Eigen::VectorXd& w, bool direct) {
  const int cols = basis_columns(poles) + (direct ? 1 : 0);
  Eigen::MatrixXcd phi(w.size(), cols);
  const cd j(0.0, 1.0);
  for (Eigen::Index l = 0; l < w.size(); ++l) {
    const cd s(0.0, w(l));
    int c = 0;
    for (const cd& p : poles) {
      if (p.imag() == 0.0) {
        phi(l, c++) = inverse(s - p);
      } else {
        const cd a = inverse(s - p), b = inverse(s - std::conj(p));
        phi(l, c++) = a + b;
        phi(l, c++) = j * a - j * b;
      }
    }
    if (direct) phi(l, c) = 1.0;
  }
  return phi;
}

std::vector<cd> residues_from_coefficients(const std::vector<cd>& poles, const Eigen::VectorXd& c) {
  std::vector<cd> r;
  int k = 0;
  for (const cd& p : poles) {
    if (p.imag() == 0.0) {
      r.emplace_back(c(k++), 0.0);
    } else {
      r.emplace_back(c(k), c(k + 1));
      k += 2;
    }
  }
  return r;
}

std::vector<cd> starting_poles(int pairs, double w_min, double w_max) {
  std::vector<cd> p;
  const double lo = std::max(w_min, 1e-3 * w_max);
  for (int i = 0; i < pairs; ++i) {
    // Linear spacing follows the usual resonance density of rotors better
    // than logarithmic spacing over one or two decades.
    const double beta = pairs == 1 ? 0.5 * (lo + w_max) : lo + (w_max - lo) * i / (pairs - 1);
    p.emplace_back(-beta / 100.0, beta);
  }
  return p;
}

GramSolver::GramSolver(const Eigen::MatrixXd& a) {
  // A^T A as a symmetric rank update: half the flops of a general product.
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(a.cols(), a.cols());
  g.selfadjointView<Eigen::Lower>().rankUpdate(a.transpose());
  factor(Eigen::MatrixXd(g.selfadjointView<Eigen::Lower>()));
}

GramSolver::GramSolver(FromGram, const Eigen::MatrixXd& gram) { factor(gram); }

void GramSolver::factor(const Eigen::MatrixXd& g) {
  // Column scales: the column norms of A, sqrt of the Gram diagonal.
  scale_ = g.diagonal().cwiseMax(0.0).cwiseSqrt().cwiseMax(1e-300).cwiseInverse();
  gram_ = scale_.asDiagonal() * g * scale_.asDiagonal();
  Eigen::LLT<Eigen::MatrixXd> llt(gram_);
  ok_ = llt.info() == Eigen::Success;
  if (ok_) chol_ = llt.matrixL();
}

Eigen::MatrixXd GramSolver::solve(const Eigen::MatrixXd& b) const {
  const Eigen::MatrixXd sb = scale_.asDiagonal() * b;
  Eigen::MatrixXd x;
  if (ok_) {
    x = chol_.triangularView<Eigen::Lower>().solve(sb);
    chol_.transpose().triangularView<Eigen::Upper>().solveInPlace(x);
  } else {
    x = gram_.colPivHouseholderQr().solve(sb);
  }
  return scale_.asDiagonal() * x;
}


Eigen::MatrixXcd derivative_basis(const std::vector<cd>& poles, const Eigen::VectorXd& w) {
  Eigen::MatrixXcd u(w.size(), basis_columns(poles));
  const cd j(0.0, 1.0);
  for (Eigen::Index l = 0; l < w.size(); ++l) {
    const cd s(0.0, w(l));
    int col = 0;
    for (const cd& p : poles) {
      const cd g = inverse((s - p) * (s - p));
      if (p.imag() == 0.0) {
        u(l, col++) = g;
      } else {
        const cd gc = inverse((s - std::conj(p)) * (s - std::conj(p)));
        u(l, col++) = g + gc;
        u(l, col++) = j * (g - gc);
      }
    }
  }
  return u;
}

bool separable_weights(const FitData& data, Eigen::VectorXd& a, Eigen::VectorXd& b) {
  const int L = data.lines(), E = data.entries();
  if (L == 0 || E == 0 || !(data.weight(0, 0) > 0)) return false;
  a = data.weight.col(0);
  b = data.weight.row(0).transpose() / data.weight(0, 0);
  for (int e = 0; e < E; ++e)
    for (int l = 0; l < L; ++l)
      if (!(std::abs(data.weight(l, e) - a(l) * b(e)) <= 1e-9 * data.weight(l, e))) return false;
  return true;
}

Eigen::MatrixXd stack_lines(const Eigen::MatrixXcd& m, const Eigen::VectorXd& a) {
  const Eigen::Index L = m.rows();
  Eigen::MatrixXd out(2 * L, m.cols());
  out.topRows(L) = a.asDiagonal() * m.real();
  out.bottomRows(L) = a.asDiagonal() * m.imag();
  return out;
}

LinearSolution solve_residues(const FitData& data, const std::vector<cd>& poles) {
  const Eigen::MatrixXcd phi = pole_basis(poles, data.w, true);
  const int n = static_cast<int>(phi.cols());
  LinearSolution out;
  out.residues.resize(data.entries(), static_cast<Eigen::Index>(poles.size()));
  out.direct.resize(data.entries());
  Eigen::VectorXd wa, wb;
  if (separable_weights(data, wa, wb)) {
    // One Gram matrix for all entries: entry e's system is b(e) times the
    // common one, so its coefficients are those of the common basis.
    const Eigen::MatrixXd a0 = stack_lines(phi, wa), y0 = stack_lines(data.h, wa);
    const Eigen::MatrixXd c = GramSolver(a0).solve(a0.transpose() * y0);
    out.cost = ((a0 * c - y0) * wb.asDiagonal()).squaredNorm();
    for (int e = 0; e < data.entries(); ++e) {
      const auto r = residues_from_coefficients(poles, c.col(e));
      for (size_t k = 0; k < r.size(); ++k) out.residues(e, static_cast<Eigen::Index>(k)) = r[k];
      out.direct(e) = c(n - 1, e);
    }
    return out;
  }
  const EntrySystems sys = solve_entries(data, phi);
  out.cost = sys.cost;
  for (int e = 0; e < data.entries(); ++e) {
    const auto r = residues_from_coefficients(poles, sys.coef.col(e));
    for (size_t k = 0; k < r.size(); ++k) out.residues(e, static_cast<Eigen::Index>(k)) = r[k];
    out.direct(e) = sys.coef(n - 1, e);
  }
  return out;
}

}  // namespace ambdiag::detail
