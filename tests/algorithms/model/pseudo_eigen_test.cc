// The real pseudo-eigen-decomposition by Hessenberg QR and inverse iteration
// (algorithms/model/src/pseudo_eigen.h) against matrices with known eigenvalues
// and against Eigen's EigenSolver.
#include "pseudo_eigen.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <complex>
#include <random>
#include <vector>

namespace ambdiag::detail {
namespace {

using cd = std::complex<double>;

Eigen::MatrixXd random_matrix(Eigen::Index n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd a(n, n);
  for (Eigen::Index j = 0; j < n; ++j)
    for (Eigen::Index i = 0; i < n; ++i) a(i, j) = g(rng);
  return a;
}

// D of T P = P D from the eigenvalues (pairs u + jv first).
Eigen::MatrixXd block_diagonal(const Eigen::VectorXcd& lam) {
  const Eigen::Index m = lam.size();
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(m, m);
  for (Eigen::Index i = 0; i < m; ++i) {
    d(i, i) = lam(i).real();
    if (lam(i).imag() == 0.0) continue;
    d(i + 1, i + 1) = lam(i).real();
    d(i, i + 1) = lam(i).imag();
    d(i + 1, i) = -lam(i).imag();
    ++i;
  }
  return d;
}

double relative_residual(const Eigen::MatrixXd& t, const PseudoEigen& e) {
  const Eigen::MatrixXd p = e.vectors();
  return (t * p - p * block_diagonal(e.eigenvalues)).norm() / (t.norm() * p.norm());
}

// Largest distance from each expected eigenvalue to the nearest computed
// one, relative to the largest modulus.
double eigenvalue_error(const Eigen::VectorXcd& got, const std::vector<cd>& expected) {
  double scale = 0.0, worst = 0.0;
  for (const cd& e : expected) scale = std::max(scale, std::abs(e));
  for (const cd& e : expected) {
    double best = 1e300;
    for (Eigen::Index i = 0; i < got.size(); ++i) best = std::min(best, std::abs(got(i) - e));
    worst = std::max(worst, best / scale);
  }
  return worst;
}

void expect_pairs_adjacent(const Eigen::VectorXcd& lam) {
  for (Eigen::Index i = 0; i < lam.size(); ++i) {
    if (lam(i).imag() == 0.0) continue;
    ASSERT_LT(i + 1, lam.size());
    EXPECT_GT(lam(i).imag(), 0.0);
    EXPECT_EQ(lam(i + 1), std::conj(lam(i)));
    ++i;
  }
}

// A = S blkdiag(...) S^-1 with the given eigenvalues (a pair as the real
// block [u v; -v u]).
Eigen::MatrixXd with_eigenvalues(const std::vector<cd>& lam, unsigned seed) {
  const Eigen::Index n = static_cast<Eigen::Index>(lam.size());
  Eigen::VectorXcd v(n);
  for (Eigen::Index i = 0; i < n; ++i) v(i) = lam[static_cast<size_t>(i)];
  const Eigen::MatrixXd s = random_matrix(n, seed) + 3.0 * Eigen::MatrixXd::Identity(n, n);
  return s * block_diagonal(v) * s.inverse();
}

TEST(PseudoEigen, RecoversKnownEigenvaluesWithPairsAndRealRoots) {
  // Poles like those of a rotor's projected shift-invert matrix: lightly
  // damped pairs of very different sizes and a few real roots.
  std::vector<cd> lam;
  for (int k = 0; k < 15; ++k) {
    const double mag = std::pow(10.0, -1.0 - 0.2 * k), zeta = 0.002 + 0.01 * k;
    lam.emplace_back(-zeta * mag, mag * std::sqrt(1.0 - zeta * zeta));
    lam.push_back(std::conj(lam.back()));
  }
  for (int k = 0; k < 6; ++k) lam.emplace_back(-0.05 * (k + 1), 0.0);
  const Eigen::MatrixXd a = with_eigenvalues(lam, 11u);
  const PseudoEigen e = pseudo_eigen(a);
  EXPECT_TRUE(e.used_inverse_iteration);
  expect_pairs_adjacent(e.eigenvalues);
  EXPECT_LT(eigenvalue_error(e.eigenvalues, lam), 1e-10);
  EXPECT_LT(relative_residual(a, e), 1e-13);
}

TEST(PseudoEigen, AgreesWithEigenSolverOnRandomMatrices) {
  for (const Eigen::Index n : {3, 4, 9, 40, 68}) {
    const Eigen::MatrixXd a = random_matrix(n, 100u + static_cast<unsigned>(n));
    const PseudoEigen e = pseudo_eigen(a);
    const Eigen::EigenSolver<Eigen::MatrixXd> ref(a);
    std::vector<cd> expected(ref.eigenvalues().data(), ref.eigenvalues().data() + n);
    EXPECT_EQ(e.eigenvalues.size(), n);
    expect_pairs_adjacent(e.eigenvalues);
    EXPECT_LT(eigenvalue_error(e.eigenvalues, expected), 1e-12) << "n = " << n;
    EXPECT_LT(relative_residual(a, e), 1e-13) << "n = " << n;
    // The pseudo-eigenvectors are regular: P^-1 exists for the pole sum.
    EXPECT_GT(e.vectors().fullPivLu().rank(), n - 1);
  }
}

TEST(PseudoEigen, HessenbergEigenvectorsAreCollinearWithEigens) {
  // A random upper Hessenberg matrix (pairs and real roots).
  Eigen::MatrixXd h = random_matrix(30, 7u);
  for (Eigen::Index j = 0; j < 30; ++j)
    for (Eigen::Index i = j + 2; i < 30; ++i) h(i, j) = 0.0;
  const Eigen::ComplexEigenSolver<Eigen::MatrixXcd> ref(h.cast<cd>());
  int pairs = 0;
  for (Eigen::Index k = 0; k < 30; ++k) {
    const cd lam = ref.eigenvalues()(k);
    pairs += lam.imag() > 0.0 ? 1 : 0;
    Eigen::VectorXcd x;
    ASSERT_TRUE(hessenberg_eigenvector(h, lam, x));
    EXPECT_NEAR(x.cwiseAbs().maxCoeff(), 1.0, 1e-14);
    const Eigen::VectorXcd y = ref.eigenvectors().col(k);
    const double cosine = std::abs(y.dot(x)) / (y.norm() * x.norm());
    EXPECT_GT(cosine, 1.0 - 1e-12) << "eigenvalue " << lam;
    EXPECT_LT((h.cast<cd>() * x - lam * x).norm() / (h.norm() * x.norm()), 1e-14);
  }
  EXPECT_GT(pairs, 3);  // the case covers complex pairs
}

TEST(PseudoEigen, NearDefectivePairKeepsTheResolvent) {
  // A 2 x 2 block [1 1; d 1] with d = 1e-12: eigenvalues 1 +- 1e-6, whose
  // eigenvectors are nearly parallel (condition ~1e6). The decomposition
  // must still reproduce the resolvent (I - mu A)^-1 b that the pole sum
  // evaluates, to the accuracy the conditioning allows.
  const Eigen::Index n = 12;
  Eigen::MatrixXd j = Eigen::MatrixXd::Zero(n, n);
  j(0, 0) = j(1, 1) = 1.0;
  j(0, 1) = 1.0;
  j(1, 0) = 1e-12;
  for (Eigen::Index i = 2; i < n; i += 2) {
    const double u = -0.1 * static_cast<double>(i), v = 0.5 + static_cast<double>(i);
    j(i, i) = j(i + 1, i + 1) = u;
    j(i, i + 1) = v;
    j(i + 1, i) = -v;
  }
  const Eigen::MatrixXd s = random_matrix(n, 5u) + 4.0 * Eigen::MatrixXd::Identity(n, n);
  const Eigen::MatrixXd a = s * j * s.inverse();
  const PseudoEigen e = pseudo_eigen(a);
  EXPECT_TRUE(e.used_inverse_iteration);  // the gap 2e-6 is above the fallback's
  EXPECT_LT(relative_residual(a, e), 1e-12);
  const Eigen::VectorXd b = random_matrix(n, 6u).col(0);
  const Eigen::MatrixXd d = block_diagonal(e.eigenvalues);
  for (const cd mu : {cd(0.2, 0.3), cd(-0.4, 2.0), cd(0.0, 0.9)}) {
    const Eigen::VectorXcd direct =
        (Eigen::MatrixXcd::Identity(n, n) - mu * a.cast<cd>()).partialPivLu().solve(b.cast<cd>());
    const Eigen::MatrixXcd pv = e.vectors().cast<cd>();
    const Eigen::VectorXcd modal =
        pv * (Eigen::MatrixXcd::Identity(n, n) - mu * d.cast<cd>()).partialPivLu().solve(Eigen::VectorXcd(e.solve(b).cast<cd>()));
    EXPECT_LT((modal - direct).norm() / direct.norm(), 1e-8) << "mu " << mu;
  }
}

TEST(PseudoEigen, MultipleEigenvaluesFallBackToEigenSolver) {
  // Every eigenvalue twice (an isotropic rotor at standstill): inverse
  // iteration cannot separate the vectors, the fallback does.
  std::vector<cd> lam;
  for (int k = 1; k <= 5; ++k) {
    const cd pole(-0.01 * k, 1.0 * k);
    for (int twice = 0; twice < 2; ++twice) {
      lam.push_back(pole);
      lam.push_back(std::conj(pole));
    }
  }
  const Eigen::MatrixXd a = with_eigenvalues(lam, 3u);
  const PseudoEigen e = pseudo_eigen(a);
  EXPECT_FALSE(e.used_inverse_iteration);
  EXPECT_LT(eigenvalue_error(e.eigenvalues, lam), 1e-6);  // a double root is accurate to sqrt(eps)
  EXPECT_LT(relative_residual(a, e), 1e-12);
}

}  // namespace
}  // namespace ambdiag::detail
