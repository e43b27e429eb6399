#include "frf_pole_sum.h"

#include <algorithm>
#include <complex>
#include <stdexcept>

#include "vector_kernels.h"

namespace ambdiag::detail {

namespace {

using cd = std::complex<double>;

bool pair_at(const Eigen::VectorXcd& lam, Eigen::Index i) { return lam(i).imag() != 0.0 && i + 1 < lam.size(); }

// The residues' columns go in blocks of 8 (two vectors of 4 doubles for the
// real parts, two for the imaginary ones).
constexpr Eigen::Index kBlock = 8;

typedef double Vec4 __attribute__((vector_size(32)));

// h(first + l, e) = sum_i g(l, i) r(i, e) for the lines l of a chunk: g is
// count x m (column-major complex), r is m x padded (row-major, padded to a
// multiple of kBlock with zeros), h column-major with leading dimension ld.
AMBDIAG_VECTOR_CLONES void accumulate(const cd* g, Eigen::Index count, Eigen::Index m, const double* r,
                                      Eigen::Index padded, Eigen::Index cols, cd* h, Eigen::Index ld) {
  for (Eigen::Index l = 0; l < count; ++l) {
    for (Eigen::Index e0 = 0; e0 < padded; e0 += kBlock) {
      Vec4 re0 = {0, 0, 0, 0}, re1 = re0, im0 = re0, im1 = re0;
      for (Eigen::Index i = 0; i < m; ++i) {
        const cd gi = g[i * count + l];
        const double* ri = r + i * padded + e0;
        Vec4 a, b;  // unaligned loads (no Vec4 return: that would change the ABI)
        __builtin_memcpy(&a, ri, sizeof a);
        __builtin_memcpy(&b, ri + 4, sizeof b);
        const double gr = gi.real(), gm = gi.imag();
        re0 += gr * a;
        re1 += gr * b;
        im0 += gm * a;
        im1 += gm * b;
      }
      const Eigen::Index n = std::min(kBlock, cols - e0);
      for (Eigen::Index k = 0; k < n; ++k) {
        const double vr = k < 4 ? re0[k] : re1[k - 4], vi = k < 4 ? im0[k] : im1[k - 4];
        h[(e0 + k) * ld + l] = cd(vr, vi);
      }
    }
  }
}

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
  // Chunks of lines whose kernel stays in cache; per line the sum over the
  // poles is a real-by-complex product with the residues.
  constexpr Eigen::Index kChunk = 64;
  const Eigen::Index lines = alpha.size(), m = eigenvalues_.size(), cols = residues_.cols();
  if (beta.size() != lines) throw std::logic_error("PoleSum: alpha and beta differ in length");
  const Eigen::Index padded = (cols + kBlock - 1) / kBlock * kBlock;
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  RowMajor r = RowMajor::Zero(m, padded);
  r.leftCols(cols) = residues_;
  Eigen::MatrixXcd h(lines, cols), g;
  for (Eigen::Index first = 0; first < lines; first += kChunk) {
    const Eigen::Index count = std::min(kChunk, lines - first);
    g.resize(count, m);
    kernel(alpha, beta, first, g);
    accumulate(g.data(), count, m, r.data(), padded, cols, h.data() + first, lines);
  }
  return h;
}

}  // namespace ambdiag::detail
