#include "frf_pole_sum.h"

#include <algorithm>
#include <complex>
#include <stdexcept>

namespace ambdiag::detail {

namespace {

using cd = std::complex<double>;

bool pair_at(const Eigen::VectorXcd& lam, Eigen::Index i) { return lam(i).imag() != 0.0 && i + 1 < lam.size(); }

}  // namespace

PoleSum::PoleSum(const Eigen::VectorXcd& eigenvalues, const Eigen::MatrixXd& left, const Eigen::MatrixXd& right)
    : eigenvalues_(eigenvalues) {
  const Eigen::Index m = eigenvalues.size(), rows = left.rows(), ins = right.cols();
  if (left.cols() != m || right.rows() != m) throw std::logic_error("PoleSum: factor sizes do not match");
  residues_.resize(m, rows * ins);
  for (Eigen::Index i = 0; i < m; ++i) {
    const bool pair = pair_at(eigenvalues, i);
    for (Eigen::Index r = 0; r < rows; ++r) {
      for (Eigen::Index c = 0; c < ins; ++c) {
        const Eigen::Index e = r * ins + c;
        if (!pair) {
          residues_(i, e) = left(r, i) * right(i, c);
          continue;
        }
        residues_(i, e) = left(r, i) * right(i, c) + left(r, i + 1) * right(i + 1, c);
        residues_(i + 1, e) = left(r, i) * right(i + 1, c) - left(r, i + 1) * right(i, c);
      }
    }
    if (pair) ++i;
  }
}

void PoleSum::kernel(const Eigen::VectorXcd& alpha, const Eigen::VectorXcd& beta, Eigen::Index first,
                     Eigen::MatrixXcd& g) const {
  const Eigen::Index lines = g.rows(), m = eigenvalues_.size();
  // Reciprocals written out (conj(z) / |z|^2): std::complex division
  // guards against overflow with a library call per element, and the
  // scales here (rad/s, their inverses) are far from the limits of double.
  for (Eigen::Index i = 0; i < m; ++i) {
    const double u = eigenvalues_(i).real(), v = eigenvalues_(i).imag();
    const bool pair = pair_at(eigenvalues_, i);
    for (Eigen::Index l = 0; l < lines; ++l) {
      const cd al = alpha(first + l), be = beta(first + l);
      const double ar = al.real() - be.real() * u, ai = al.imag() - be.imag() * u;
      if (!pair) {
        const double s = 1.0 / (ar * ar + ai * ai);
        g(l, i) = {ar * s, -ai * s};
        continue;
      }
      const double br = be.real() * v, bi = be.imag() * v;
      const double dr = ar * ar - ai * ai + br * br - bi * bi, di = 2.0 * (ar * ai + br * bi);
      const double s = 1.0 / (dr * dr + di * di), ir = dr * s, ii = -di * s;
      g(l, i) = {ar * ir - ai * ii, ar * ii + ai * ir};
      g(l, i + 1) = {br * ir - bi * ii, br * ii + bi * ir};
    }
    if (pair) ++i;
  }
}

Eigen::MatrixXcd PoleSum::evaluate(const Eigen::VectorXcd& alpha, const Eigen::VectorXcd& beta) const {
  // A complex matrix is stored as interleaved (re, im) pairs, so a chunk of
  // the complex kernel is a real matrix of twice the rows, and its product
  // with the real residues is the complex result in the same layout.
  constexpr Eigen::Index kChunk = 64;
  const Eigen::Index lines = alpha.size(), m = eigenvalues_.size(), cols = residues_.cols();
  if (beta.size() != lines) throw std::logic_error("PoleSum: alpha and beta differ in length");
  Eigen::MatrixXcd h(lines, cols), g;
  for (Eigen::Index first = 0; first < lines; first += kChunk) {
    const Eigen::Index count = std::min(kChunk, lines - first);
    g.resize(count, m);
    kernel(alpha, beta, first, g);
    const Eigen::Map<const Eigen::MatrixXd> gr(reinterpret_cast<const double*>(g.data()), 2 * count, m);
    Eigen::Map<Eigen::MatrixXd, 0, Eigen::OuterStride<>> hr(reinterpret_cast<double*>(h.data()) + 2 * first, 2 * count,
                                                           cols, Eigen::OuterStride<>(2 * lines));
    hr.noalias() = gr * residues_;
  }
  return h;
}

}  // namespace ambdiag::detail
