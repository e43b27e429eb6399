// Small dense kernels on the hot paths of the FRF synthesis, compiled twice
// by GCC's target_clones: for x86-64-v3 (AVX2 and FMA, four doubles per
// instruction) and for the baseline, one picked at load time, so the build
// itself stays generic x86-64 (private to the algorithms library).
#pragma once

#include <Eigen/Core>

namespace ambdiag::detail {

// c (k x p, column-major) = V^T W for V (n x k) and W (n x p), column-major
// with leading dimension n.
void gram(const double* v, Eigen::Index n, Eigen::Index k, const double* w, Eigen::Index p, double* c);

// W -= V c (shapes as in gram).
void subtract_product(const double* v, Eigen::Index n, Eigen::Index k, const double* c, Eigen::Index p, double* w);

// Complex vectors stored as separate real and imaginary parts:
// y -= l x over n entries,
void complex_axpy(double l_re, double l_im, const double* x_re, const double* x_im, double* y_re, double* y_im,
                  Eigen::Index n);
// and the sum of a_i b_i (no conjugate) as (re, im).
void complex_dot(const double* a_re, const double* a_im, const double* b_re, const double* b_im, Eigen::Index n,
                 double* re, double* im);

// X <- U^-1 L^-1 X for the packed LU factors of a partial-pivoting LU
// (n x n column-major: unit lower L below the diagonal, U on and above it;
// the row permutation is the caller's), X n x cols with leading dimension n.
void lu_solve_in_place(const double* lu, Eigen::Index n, double* x, Eigen::Index cols);

// A reflector applied from the right to n rows of two or three columns
// (c2 null for two): t = x c0 + y c1 [+ z c2]; c0 -= t, c1 -= t q [, c2 -= t r].
void reflect_columns(double* c0, double* c1, double* c2, Eigen::Index n, double x, double y, double z, double q,
                     double r);

// Householder reflector I - tau v v^T (v of length len) applied to a block
// of a column-major matrix with leading dimension ld: from the left to
// rows [0, len) of `cols` columns, or from the right to columns [0, len)
// of `rows` rows (a points at the block's first entry).
void reflect_left(double* a, Eigen::Index ld, Eigen::Index len, Eigen::Index cols, const double* v, double tau);
void reflect_right(double* a, Eigen::Index ld, Eigen::Index rows, Eigen::Index len, const double* v, double tau,
                   double* work);

}  // namespace ambdiag::detail

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define AMBDIAG_VECTOR_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define AMBDIAG_VECTOR_CLONES
#endif
