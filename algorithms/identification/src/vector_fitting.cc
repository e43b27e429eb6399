// Relaxed vector fitting with common poles (Gustavsen & Semlyen 1999;
// relaxation: Gustavsen 2006; per-entry QR elimination of the residues:
// Deschrijver, Mrozowski, Dhaene & De Zutter 2008).
#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "fit_data.h"

namespace ambdiag::detail {

namespace {

// Zeros of sigma(s) = c^T (sI - A)^-1 b + d in the real realisation of the
// pole set: eig(A - b c^T / d).
std::vector<cd> sigma_zeros(const std::vector<cd>& poles, const Eigen::VectorXd& c, double d) {
  const int n = basis_columns(poles);
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(n);
  int k = 0;
  for (const cd& p : poles) {
    if (p.imag() == 0.0) {
      a(k, k) = p.real();
      b(k) = 1.0;
      ++k;
    } else {
      a(k, k) = p.real();
      a(k, k + 1) = p.imag();
      a(k + 1, k) = -p.imag();
      a(k + 1, k + 1) = p.real();
      b(k) = 2.0;
      k += 2;
    }
  }
  const Eigen::MatrixXd h = a - b * c.transpose() / d;
  const Eigen::VectorXcd z = Eigen::EigenSolver<Eigen::MatrixXd>(h, false).eigenvalues();
  std::vector<cd> out;
  for (Eigen::Index i = 0; i < z.size(); ++i) {
    cd p = z(i);
    const double mag = std::abs(p);
    if (std::abs(p.imag()) <= 1e-9 * mag) p = cd(p.real(), 0.0);
    if (p.imag() < 0.0) continue;  // keep one of each conjugate pair
    // Stability: reflect right-half-plane poles; nudge exact zeros left.
    if (p.real() > 0.0) p = cd(-p.real(), p.imag());
    if (p.real() == 0.0) p = cd(-1e-6 * std::max(mag, 1.0), p.imag());
    out.push_back(p);
  }
  std::sort(out.begin(), out.end(), [](const cd& x, const cd& y) { return std::abs(x) < std::abs(y); });
  return out;
}

// The block R22 of the QR factorisation of m = [A B] (A: the residue
// columns, eliminated): any S with S^T S = B^T B - B^T A (A^T A)^-1 A^T B
// serves, so it is the Cholesky factor of that Schur complement of the Gram
// matrix g = m^T m; a Householder QR of m (built by `make_m`) where the
// complement is not numerically positive definite.
template <class MakeM>
Eigen::MatrixXd sigma_block(const Eigen::MatrixXd& g, int n1, MakeM make_m) {
  Eigen::LLT<Eigen::MatrixXd> aa(g.topLeftCorner(n1, n1));
  if (aa.info() == Eigen::Success) {
    const Eigen::MatrixXd x = aa.matrixL().solve(g.topRightCorner(n1, n1));
    const Eigen::MatrixXd schur = g.bottomRightCorner(n1, n1) - x.transpose() * x;
    Eigen::LLT<Eigen::MatrixXd> s(schur);
    if (s.info() == Eigen::Success) return s.matrixU();
  }
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(make_m());
  return qr.matrixQR().block(n1, n1, n1, n1).triangularView<Eigen::Upper>();
}

}  // namespace

std::vector<cd> vector_fit(const FitData& data, std::vector<cd> poles, int iterations) {
  const int L = data.lines(), E = data.entries();
  for (int it = 0; it < iterations; ++it) {
    const Eigen::MatrixXcd phi = pole_basis(poles, data.w, true);  // L x (N+1)
    const int n1 = static_cast<int>(phi.cols());
    // Column scales so the per-entry QR sees columns of similar size.
    Eigen::VectorXd col_scale(n1);
    for (int c = 0; c < n1; ++c) col_scale(c) = 1.0 / std::max(phi.col(c).norm(), 1e-300);

    Eigen::MatrixXd stacked(E * n1 + 1, n1);
    // Gram matrix of entry e's m = [A B], A = w phi, B = -w h phi / |h|_rms
    // (columns scaled), from per-line products of the basis weighted per
    // entry (entry_grams): A^T A and B^T B from sum w^2 Re(conj phi_i phi_j)
    // and w^2 |h|^2 times the same, A^T B from w^2 Re h and w^2 Im h times
    // Re and Im of conj phi_i phi_j. A quarter of the flops of m^T m.
    Eigen::VectorXd hnorm(E);
    for (int e = 0; e < E; ++e) hnorm(e) = std::sqrt((data.weight.col(e).cwiseProduct(data.h.col(e).cwiseAbs())).squaredNorm() / L);
    const Eigen::MatrixXd w2 = data.weight.cwiseAbs2();
    Eigen::MatrixXd wr(L, 3 * E), wi(L, E);
    for (int e = 0; e < E; ++e) {
      const double hn = std::max(hnorm(e), 1e-300);
      wr.col(e) = w2.col(e);
      wr.col(E + e) = -w2.col(e).cwiseProduct(data.h.col(e).real()) / hn;
      wr.col(2 * E + e) = w2.col(e).cwiseProduct(data.h.col(e).cwiseAbs2()) / (hn * hn);
      wi.col(e) = w2.col(e).cwiseProduct(data.h.col(e).imag()) / hn;
    }
    const Eigen::MatrixXd gr = entry_grams(phi, wr), gi = entry_grams_imag(phi, wi);
    double total = 0.0;
    for (int e = 0; e < E; ++e) {
      total += hnorm(e) * hnorm(e);
      const Eigen::MatrixXd aa = unpack_gram(gr.row(e).transpose(), n1), bb = unpack_gram(gr.row(2 * E + e).transpose(), n1);
      const Eigen::MatrixXd re_h = unpack_gram(gr.row(E + e).transpose(), n1);
      // sum w^2 Im h Im(conj phi_i phi_j), antisymmetric.
      Eigen::MatrixXd im_h = Eigen::MatrixXd::Zero(n1, n1);
      Eigen::Index k = 0;
      for (int j = 1; j < n1; ++j)
        for (int i = 0; i < j; ++i, ++k) {
          im_h(i, j) = gi(e, k);
          im_h(j, i) = -gi(e, k);
        }
      // A_i^T B_j = -sum w^2 Re(conj phi_i h phi_j) / hn.
      Eigen::MatrixXd g(2 * n1, 2 * n1);
      g.topLeftCorner(n1, n1) = aa;
      g.topRightCorner(n1, n1) = re_h + im_h;
      g.bottomLeftCorner(n1, n1) = g.topRightCorner(n1, n1).transpose();
      g.bottomRightCorner(n1, n1) = bb;
      Eigen::VectorXd cs2(2 * n1);
      cs2 << col_scale, col_scale;
      g = cs2.asDiagonal() * g * cs2.asDiagonal();
      auto make_m = [&]() {
        Eigen::MatrixXd m(2 * L, 2 * n1);
        for (int l = 0; l < L; ++l) {
          const double wt = data.weight(l, e);
          const cd wh = wt * data.h(l, e);
          for (int c = 0; c < n1; ++c) {
            const cd a = wt * phi(l, c) * col_scale(c);
            const cd b = -wh * phi(l, c) * col_scale(c) / std::max(hnorm(e), 1e-300);
            m(l, c) = a.real();
            m(L + l, c) = a.imag();
            m(l, n1 + c) = b.real();
            m(L + l, n1 + c) = b.imag();
          }
        }
        return m;
      };
      // Scale back so every entry's block weighs by its own data.
      stacked.block(e * n1, 0, n1, n1) = sigma_block(g, n1, make_m) * hnorm(e);
    }
    // Relaxation: Re sum_l sigma(s_l) = L, weighted like the data.
    const double relax = std::sqrt(total / E);
    for (int c = 0; c < n1; ++c) stacked(E * n1, c) = relax * phi.col(c).real().sum() * col_scale(c) / L;
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(E * n1 + 1);
    rhs(E * n1) = relax;
    Eigen::VectorXd x = stacked.colPivHouseholderQr().solve(rhs);
    x = x.cwiseProduct(col_scale);
    double d = x(n1 - 1);
    if (std::abs(d) < 1e-8) d = d < 0 ? -1e-8 : 1e-8;
    poles = sigma_zeros(poles, x.head(n1 - 1), d);
  }
  return poles;
}

}  // namespace ambdiag::detail
