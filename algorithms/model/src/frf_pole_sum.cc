#include "frf_pole_sum.h"

#include <algorithm>
#include <complex>
#include <stdexcept>
#include <vector>

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
// count x m (column-major, real and imaginary parts apart), r is m x padded (row-major, padded to a
// multiple of kBlock with zeros), h column-major with leading dimension ld.
AMBDIAG_VECTOR_CLONES void accumulate(const double* g_re, const double* g_im, Eigen::Index count, Eigen::Index m,
                                      const double* r, Eigen::Index padded, Eigen::Index cols, cd* h, Eigen::Index ld) {
  // Two lines at a time: each residue load feeds eight multiply-adds.
  for (Eigen::Index l = 0; l < count; l += 2) {
    const Eigen::Index l1 = std::min(l + 1, count - 1);  // an odd count repeats its last line
    for (Eigen::Index e0 = 0; e0 < padded; e0 += kBlock) {
      Vec4 re0 = {0, 0, 0, 0}, re1 = re0, im0 = re0, im1 = re0, se0 = re0, se1 = re0, sm0 = re0, sm1 = re0;
      for (Eigen::Index i = 0; i < m; ++i) {
        const double gr = g_re[i * count + l], gm = g_im[i * count + l];
        const double hr = g_re[i * count + l1], hm = g_im[i * count + l1];
        const double* ri = r + i * padded + e0;
        Vec4 a, b;  // unaligned loads (no Vec4 return: that would change the ABI)
        __builtin_memcpy(&a, ri, sizeof a);
        __builtin_memcpy(&b, ri + 4, sizeof b);
        re0 += gr * a;
        re1 += gr * b;
        im0 += gm * a;
        im1 += gm * b;
        se0 += hr * a;
        se1 += hr * b;
        sm0 += hm * a;
        sm1 += hm * b;
      }
      const Eigen::Index n = std::min(kBlock, cols - e0);
      for (Eigen::Index k = 0; k < n; ++k) {
        const Eigen::Index c = (e0 + k) * ld;
        h[c + l] = k < 4 ? cd(re0[k], im0[k]) : cd(re1[k - 4], im1[k - 4]);
        h[c + l1] = k < 4 ? cd(se0[k], sm0[k]) : cd(se1[k - 4], sm1[k - 4]);
      }
    }
  }
}

// The coefficients g(l, i) of the residue rows on the lines of a chunk
// (alpha, beta per line with real and imaginary parts apart): a real pole d
// gives 1 / (alpha - beta d); a pair u +- jv, with a = alpha - beta u and
// b = beta v, gives a / (a^2 + b^2) and b / (a^2 + b^2) for its two rows.
// Reciprocals written out (conj(z) / |z|^2): std::complex division guards
// against overflow with a library call per element, and the scales here
// (rad/s, their inverses) are far from the limits of double.
AMBDIAG_VECTOR_CLONES void pole_kernel(const double* al_re, const double* al_im, const double* be_re,
                                       const double* be_im, Eigen::Index count, const cd* poles, const char* pair,
                                       Eigen::Index m, double* g_re, double* g_im) {
  const Eigen::Index c4 = count / 4 * 4;
  for (Eigen::Index i = 0; i < m; ++i) {
    const double u = poles[i].real(), v = poles[i].imag();
    double *r0 = g_re + i * count, *i0 = g_im + i * count;
    if (!pair[i]) {
      for (Eigen::Index l = 0; l < c4; l += 4) {
        Vec4 ar, ai, br, bi;
        __builtin_memcpy(&ar, al_re + l, sizeof ar);
        __builtin_memcpy(&ai, al_im + l, sizeof ai);
        __builtin_memcpy(&br, be_re + l, sizeof br);
        __builtin_memcpy(&bi, be_im + l, sizeof bi);
        const Vec4 xr = ar - br * u, xi = ai - bi * u;
        const Vec4 sc = 1.0 / (xr * xr + xi * xi), gr = xr * sc, gi = -xi * sc;
        __builtin_memcpy(r0 + l, &gr, sizeof gr);
        __builtin_memcpy(i0 + l, &gi, sizeof gi);
      }
      for (Eigen::Index l = c4; l < count; ++l) {
        const double xr = al_re[l] - be_re[l] * u, xi = al_im[l] - be_im[l] * u;
        const double sc = 1.0 / (xr * xr + xi * xi);
        r0[l] = xr * sc;
        i0[l] = -xi * sc;
      }
      continue;
    }
    double *r1 = g_re + (i + 1) * count, *i1 = g_im + (i + 1) * count;
    for (Eigen::Index l = 0; l < c4; l += 4) {
      Vec4 ar, ai, br, bi;
      __builtin_memcpy(&ar, al_re + l, sizeof ar);
      __builtin_memcpy(&ai, al_im + l, sizeof ai);
      __builtin_memcpy(&br, be_re + l, sizeof br);
      __builtin_memcpy(&bi, be_im + l, sizeof bi);
      const Vec4 xr = ar - br * u, xi = ai - bi * u, yr = br * v, yi = bi * v;
      const Vec4 dr = xr * xr - xi * xi + yr * yr - yi * yi, di = 2.0 * (xr * xi + yr * yi);
      const Vec4 sc = 1.0 / (dr * dr + di * di), ir = dr * sc, ii = -di * sc;
      const Vec4 g0r = xr * ir - xi * ii, g0i = xr * ii + xi * ir, g1r = yr * ir - yi * ii, g1i = yr * ii + yi * ir;
      __builtin_memcpy(r0 + l, &g0r, sizeof g0r);
      __builtin_memcpy(i0 + l, &g0i, sizeof g0i);
      __builtin_memcpy(r1 + l, &g1r, sizeof g1r);
      __builtin_memcpy(i1 + l, &g1i, sizeof g1i);
    }
    for (Eigen::Index l = c4; l < count; ++l) {
      const double xr = al_re[l] - be_re[l] * u, xi = al_im[l] - be_im[l] * u, yr = be_re[l] * v, yi = be_im[l] * v;
      const double dr = xr * xr - xi * xi + yr * yr - yi * yi, di = 2.0 * (xr * xi + yr * yi);
      const double sc = 1.0 / (dr * dr + di * di), ir = dr * sc, ii = -di * sc;
      r0[l] = xr * ir - xi * ii;
      i0[l] = xr * ii + xi * ir;
      r1[l] = yr * ir - yi * ii;
      i1[l] = yr * ii + yi * ir;
    }
    ++i;
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
  // The kernel for a chunk, real and imaginary parts apart.
  std::vector<char> pair(static_cast<size_t>(m), 0);
  for (Eigen::Index i = 0; i < m; ++i)
    if (pair_at(eigenvalues_, i)) pair[static_cast<size_t>(i++)] = 1;
  Eigen::MatrixXd ab(kChunk, 4), g_re(kChunk, m), g_im(kChunk, m);
  Eigen::MatrixXcd h(lines, cols);
  for (Eigen::Index first = 0; first < lines; first += kChunk) {
    const Eigen::Index count = std::min(kChunk, lines - first);
    for (Eigen::Index l = 0; l < count; ++l) {
      ab(l, 0) = alpha(first + l).real();
      ab(l, 1) = alpha(first + l).imag();
      ab(l, 2) = beta(first + l).real();
      ab(l, 3) = beta(first + l).imag();
    }
    pole_kernel(ab.col(0).data(), ab.col(1).data(), ab.col(2).data(), ab.col(3).data(), count, eigenvalues_.data(),
                pair.data(), m, g_re.data(), g_im.data());
    accumulate(g_re.data(), g_im.data(), count, m, r.data(), padded, cols, h.data() + first, lines);
  }
  return h;
}

}  // namespace ambdiag::detail
