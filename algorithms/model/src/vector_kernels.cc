#include "vector_kernels.h"

namespace ambdiag::detail {

namespace {

typedef double Vec4 __attribute__((vector_size(32)));

}  // namespace

AMBDIAG_VECTOR_CLONES void gram(const double* v, Eigen::Index n, Eigen::Index k, const double* w, Eigen::Index p,
                                double* c) {
  const Eigen::Index n4 = n / 4 * 4;
  // V streamed once (j outer): for a large system W stays in cache, V not.
  for (Eigen::Index j = 0; j < k; ++j) {
    const double* vj = v + j * n;
    for (Eigen::Index q = 0; q < p; ++q) {
      const double* wq = w + q * n;
      Vec4 acc = {0, 0, 0, 0};
      for (Eigen::Index i = 0; i < n4; i += 4) {
        Vec4 a, b;  // unaligned loads
        __builtin_memcpy(&a, vj + i, sizeof a);
        __builtin_memcpy(&b, wq + i, sizeof b);
        acc += a * b;
      }
      double s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
      for (Eigen::Index i = n4; i < n; ++i) s += vj[i] * wq[i];
      c[q * k + j] = s;
    }
  }
}

AMBDIAG_VECTOR_CLONES void subtract_product(const double* v, Eigen::Index n, Eigen::Index k, const double* c,
                                            Eigen::Index p, double* w) {
  const Eigen::Index n4 = n / 4 * 4;
  for (Eigen::Index j = 0; j < k; ++j) {
    const double* vj = v + j * n;
    for (Eigen::Index q = 0; q < p; ++q) {
      double* wq = w + q * n;
      const double f = c[q * k + j];
      for (Eigen::Index i = 0; i < n4; i += 4) {
        Vec4 a, b;
        __builtin_memcpy(&a, vj + i, sizeof a);
        __builtin_memcpy(&b, wq + i, sizeof b);
        b -= f * a;
        __builtin_memcpy(wq + i, &b, sizeof b);
      }
      for (Eigen::Index i = n4; i < n; ++i) wq[i] -= f * vj[i];
    }
  }
}

AMBDIAG_VECTOR_CLONES void complex_axpy(double l_re, double l_im, const double* x_re, const double* x_im, double* y_re,
                                        double* y_im, Eigen::Index n) {
  const Eigen::Index n4 = n / 4 * 4;
  for (Eigen::Index i = 0; i < n4; i += 4) {
    Vec4 xr, xi, yr, yi;
    __builtin_memcpy(&xr, x_re + i, sizeof xr);
    __builtin_memcpy(&xi, x_im + i, sizeof xi);
    __builtin_memcpy(&yr, y_re + i, sizeof yr);
    __builtin_memcpy(&yi, y_im + i, sizeof yi);
    yr -= l_re * xr - l_im * xi;
    yi -= l_re * xi + l_im * xr;
    __builtin_memcpy(y_re + i, &yr, sizeof yr);
    __builtin_memcpy(y_im + i, &yi, sizeof yi);
  }
  for (Eigen::Index i = n4; i < n; ++i) {
    y_re[i] -= l_re * x_re[i] - l_im * x_im[i];
    y_im[i] -= l_re * x_im[i] + l_im * x_re[i];
  }
}

AMBDIAG_VECTOR_CLONES void complex_dot(const double* a_re, const double* a_im, const double* b_re, const double* b_im,
                                       Eigen::Index n, double* re, double* im) {
  const Eigen::Index n4 = n / 4 * 4;
  Vec4 rr = {0, 0, 0, 0}, ii = rr, ri = rr, ir = rr;
  for (Eigen::Index i = 0; i < n4; i += 4) {
    Vec4 ar, ai, br, bi;
    __builtin_memcpy(&ar, a_re + i, sizeof ar);
    __builtin_memcpy(&ai, a_im + i, sizeof ai);
    __builtin_memcpy(&br, b_re + i, sizeof br);
    __builtin_memcpy(&bi, b_im + i, sizeof bi);
    rr += ar * br;
    ii += ai * bi;
    ri += ar * bi;
    ir += ai * br;
  }
  const Vec4 r = rr - ii, m = ri + ir;
  double sr = (r[0] + r[1]) + (r[2] + r[3]), si = (m[0] + m[1]) + (m[2] + m[3]);
  for (Eigen::Index i = n4; i < n; ++i) {
    sr += a_re[i] * b_re[i] - a_im[i] * b_im[i];
    si += a_re[i] * b_im[i] + a_im[i] * b_re[i];
  }
  *re = sr;
  *im = si;
}

namespace {

// y -= a x over n entries.
inline void axpy_minus(double a, const double* x, double* y, Eigen::Index n) {
  const Eigen::Index n4 = n / 4 * 4;
  for (Eigen::Index i = 0; i < n4; i += 4) {
    Vec4 xv, yv;
    __builtin_memcpy(&xv, x + i, sizeof xv);
    __builtin_memcpy(&yv, y + i, sizeof yv);
    yv -= a * xv;
    __builtin_memcpy(y + i, &yv, sizeof yv);
  }
  for (Eigen::Index i = n4; i < n; ++i) y[i] -= a * x[i];
}

}  // namespace

AMBDIAG_VECTOR_CLONES void lu_solve_in_place(const double* lu, Eigen::Index n, double* x, Eigen::Index cols) {
  // Column-oriented substitutions: the inner loops run down contiguous
  // columns of the factors.
  for (Eigen::Index q = 0; q < cols; ++q) {
    double* xq = x + q * n;
    for (Eigen::Index j = 0; j + 1 < n; ++j) axpy_minus(xq[j], lu + j * n + j + 1, xq + j + 1, n - j - 1);
    for (Eigen::Index j = n - 1; j >= 0; --j) {
      xq[j] /= lu[j * n + j];
      axpy_minus(xq[j], lu + j * n, xq, j);
    }
  }
}

AMBDIAG_VECTOR_CLONES void reflect_columns(double* c0, double* c1, double* c2, Eigen::Index n, double x, double y,
                                           double z, double q, double r) {
  const Eigen::Index n4 = n / 4 * 4;
  if (c2 == nullptr) {
    for (Eigen::Index i = 0; i < n; ++i) {
      const double t = x * c0[i] + y * c1[i];
      c1[i] -= t * q;
      c0[i] -= t;
    }
    return;
  }
  for (Eigen::Index i = 0; i < n4; i += 4) {
    Vec4 a, b, c;
    __builtin_memcpy(&a, c0 + i, sizeof a);
    __builtin_memcpy(&b, c1 + i, sizeof b);
    __builtin_memcpy(&c, c2 + i, sizeof c);
    const Vec4 t = x * a + y * b + z * c;
    a -= t;
    b -= t * q;
    c -= t * r;
    __builtin_memcpy(c0 + i, &a, sizeof a);
    __builtin_memcpy(c1 + i, &b, sizeof b);
    __builtin_memcpy(c2 + i, &c, sizeof c);
  }
  for (Eigen::Index i = n4; i < n; ++i) {
    const double t = x * c0[i] + y * c1[i] + z * c2[i];
    c2[i] -= t * r;
    c1[i] -= t * q;
    c0[i] -= t;
  }
}

AMBDIAG_VECTOR_CLONES void reflect_left(double* a, Eigen::Index ld, Eigen::Index len, Eigen::Index cols,
                                        const double* v, double tau) {
  const Eigen::Index n4 = len / 4 * 4;
  for (Eigen::Index j = 0; j < cols; ++j) {
    double* c = a + j * ld;
    Vec4 acc = {0, 0, 0, 0};
    for (Eigen::Index i = 0; i < n4; i += 4) {
      Vec4 x, y;
      __builtin_memcpy(&x, v + i, sizeof x);
      __builtin_memcpy(&y, c + i, sizeof y);
      acc += x * y;
    }
    double s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for (Eigen::Index i = n4; i < len; ++i) s += v[i] * c[i];
    axpy_minus(tau * s, v, c, len);
  }
}

AMBDIAG_VECTOR_CLONES void reflect_right(double* a, Eigen::Index ld, Eigen::Index rows, Eigen::Index len,
                                         const double* v, double tau, double* work) {
  for (Eigen::Index i = 0; i < rows; ++i) work[i] = 0.0;
  for (Eigen::Index j = 0; j < len; ++j) axpy_minus(-v[j], a + j * ld, work, rows);  // work = A v
  for (Eigen::Index j = 0; j < len; ++j) axpy_minus(tau * v[j], work, a + j * ld, rows);
}

}  // namespace ambdiag::detail
