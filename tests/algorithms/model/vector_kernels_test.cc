// The vector kernels of the FRF synthesis (algorithms/model/src/vector_kernels.h)
// and the pole sum built on them, against plain Eigen arithmetic, on sizes
// that exercise the remainders of the 4-wide loops.
#include "vector_kernels.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <complex>
#include <random>

#include "frf_pole_sum.h"

namespace ambdiag::detail {
namespace {

using cd = std::complex<double>;

Eigen::MatrixXd random_matrix(Eigen::Index rows, Eigen::Index cols, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixXd a(rows, cols);
  for (Eigen::Index j = 0; j < cols; ++j)
    for (Eigen::Index i = 0; i < rows; ++i) a(i, j) = u(rng);
  return a;
}

TEST(VectorKernels, GramAndSubtractProductMatchEigen) {
  for (const Eigen::Index n : {1, 3, 4, 5, 11, 176}) {
    const Eigen::MatrixXd v = random_matrix(n, 7, 1u), w = random_matrix(n, 3, 2u);
    Eigen::MatrixXd c(7, 3);
    gram(v.data(), n, 7, w.data(), 3, c.data());
    EXPECT_LT((c - v.transpose() * w).norm(), 1e-13 * (1.0 + c.norm())) << "n = " << n;
    Eigen::MatrixXd x = w;
    subtract_product(v.data(), n, 7, c.data(), 3, x.data());
    EXPECT_LT((x - (w - v * c)).norm(), 1e-13 * (1.0 + x.norm())) << "n = " << n;
  }
}

TEST(VectorKernels, ComplexAxpyAndDotMatchStdComplex) {
  for (const Eigen::Index n : {0, 1, 6, 9}) {
    const Eigen::MatrixXd a = random_matrix(n, 4, 3u);
    const cd l(0.3, -1.7);
    Eigen::VectorXd yr = a.col(2), yi = a.col(3);
    complex_axpy(l.real(), l.imag(), a.col(0).data(), a.col(1).data(), yr.data(), yi.data(), n);
    double dot_re = 0.0, dot_im = 0.0;
    complex_dot(a.col(0).data(), a.col(1).data(), a.col(2).data(), a.col(3).data(), n, &dot_re, &dot_im);
    const cd dot(dot_re, dot_im);
    cd expected_dot = 0.0;
    for (Eigen::Index i = 0; i < n; ++i) {
      const cd x(a(i, 0), a(i, 1)), y(a(i, 2), a(i, 3));
      const cd z = y - l * x;
      EXPECT_NEAR(yr(i), z.real(), 1e-15);
      EXPECT_NEAR(yi(i), z.imag(), 1e-15);
      expected_dot += x * y;
    }
    EXPECT_NEAR(std::abs(dot - expected_dot), 0.0, 1e-14);
  }
}

TEST(VectorKernels, LuSolveInPlaceMatchesEigen) {
  for (const Eigen::Index n : {1, 2, 7, 13}) {
    const Eigen::MatrixXd a = random_matrix(n, n, 4u) + 3.0 * Eigen::MatrixXd::Identity(n, n);
    const Eigen::MatrixXd b = random_matrix(n, 3, 5u);
    const Eigen::PartialPivLU<Eigen::MatrixXd> lu(a);
    Eigen::MatrixXd x = lu.permutationP() * b;
    lu_solve_in_place(lu.matrixLU().data(), n, x.data(), 3);
    EXPECT_LT((a * x - b).norm(), 1e-13 * b.norm()) << "n = " << n;
  }
}

TEST(VectorKernels, ReflectColumnsAppliesTheReflector) {
  for (const Eigen::Index n : {1, 5, 8}) {
    const Eigen::MatrixXd c = random_matrix(n, 3, 6u);
    const double x = 1.2, y = -0.4, z = 0.7, q = 0.3, r = -0.9;
    Eigen::MatrixXd three = c, two = c;
    reflect_columns(three.col(0).data(), three.col(1).data(), three.col(2).data(), n, x, y, z, q, r);
    reflect_columns(two.col(0).data(), two.col(1).data(), nullptr, n, x, y, z, q, r);
    for (Eigen::Index i = 0; i < n; ++i) {
      const double t3 = x * c(i, 0) + y * c(i, 1) + z * c(i, 2), t2 = x * c(i, 0) + y * c(i, 1);
      EXPECT_NEAR(three(i, 0), c(i, 0) - t3, 1e-15);
      EXPECT_NEAR(three(i, 1), c(i, 1) - t3 * q, 1e-15);
      EXPECT_NEAR(three(i, 2), c(i, 2) - t3 * r, 1e-15);
      EXPECT_NEAR(two(i, 0), c(i, 0) - t2, 1e-15);
      EXPECT_NEAR(two(i, 1), c(i, 1) - t2 * q, 1e-15);
      EXPECT_EQ(two(i, 2), c(i, 2));
    }
  }
}

TEST(PoleSum, MatchesTheResolventOnAnOddNumberOfLines) {
  // D with two pairs and a real pole, L and R random: H = L (alpha I -
  // beta D)^-1 R in complex arithmetic, on 131 lines (chunks of 64 and a
  // remainder of 3, odd).
  const cd p1(-0.2, 3.0), p2(-0.05, 7.0);
  Eigen::VectorXcd lam(5);
  lam << p1, std::conj(p1), -1.5, p2, std::conj(p2);
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(5, 5);
  d(0, 0) = d(1, 1) = p1.real();
  d(0, 1) = p1.imag();
  d(1, 0) = -p1.imag();
  d(2, 2) = -1.5;
  d(3, 3) = d(4, 4) = p2.real();
  d(3, 4) = p2.imag();
  d(4, 3) = -p2.imag();
  const Eigen::MatrixXd l = random_matrix(3, 5, 7u), r = random_matrix(5, 3, 8u);
  const Eigen::Index lines = 131;
  Eigen::VectorXcd alpha(lines), beta(lines);
  for (Eigen::Index k = 0; k < lines; ++k) {
    alpha(k) = cd(0.0, 0.1 * static_cast<double>(k));
    beta(k) = cd(1.0, 0.01 * static_cast<double>(k % 5));
  }
  const Eigen::MatrixXcd h = PoleSum(lam, l, r).evaluate(alpha, beta);
  ASSERT_EQ(h.rows(), lines);
  ASSERT_EQ(h.cols(), 9);
  for (Eigen::Index k = 0; k < lines; ++k) {
    const Eigen::MatrixXcd ref = l.cast<cd>() *
                                 (alpha(k) * Eigen::MatrixXcd::Identity(5, 5) - beta(k) * d.cast<cd>()).inverse() *
                                 r.cast<cd>();
    for (Eigen::Index o = 0; o < 3; ++o)
      for (Eigen::Index i = 0; i < 3; ++i)
        EXPECT_LT(std::abs(h(k, o * 3 + i) - ref(o, i)), 1e-12 * (1.0 + std::abs(ref(o, i)))) << "line " << k;
  }
}

}  // namespace
}  // namespace ambdiag::detail
