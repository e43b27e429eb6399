// Real pseudo-eigen-decomposition of a small dense nonsymmetric matrix for
// the pole sums of the FRF synthesis (private to the algorithms library):
//   T P = P D,  D block diagonal with 1 x 1 blocks d and 2 x 2 blocks
//   [u v; -v u] for the pair u +- jv (v > 0), P real,
// the form of Eigen's EigenSolver (pseudoEigenvectors), at about 40 % of
// its cost (m = 68: ~10 M instructions against 24.8 M): T = Q H Q^T (Householder Hessenberg reduction), the eigenvalues of H
// by Francis double-shift QR without Schur vectors, and the eigenvector of
// H for each pole by inverse iteration on the Hessenberg form (O(m^2) per
// pole, as LAPACK dhsein / dlaein; Wilkinson, The Algebraic Eigenvalue
// Problem, 1965, ch. 9), P = Q X. For the pair u + jv the complex
// eigenvector x = a + jb gives the columns a, b (T (a + jb) = (u + jv)(a + jb)).
//
// Eigenvalues closer than 1e-10 ||T|| to each other (e.g. the double
// eigenvalues of an isotropic rotor at standstill), or an eigenvector that
// inverse iteration does not resolve, send the whole matrix to Eigen's
// EigenSolver (used_inverse_iteration false): inverse iteration from one
// start vector cannot separate the vectors of a multiple eigenvalue.
#pragma once

#include <complex>

#include <Eigen/Core>
#include <Eigen/LU>

namespace ambdiag::detail {

// P is kept as Q X: the pole sums need only L P and P^-1 R for a few rows
// of L and columns of R, and forming P would cost an m^3 product.
struct PseudoEigen {
  Eigen::VectorXcd eigenvalues;  // a pair adjacent, u + jv (v > 0) first
  bool used_inverse_iteration = true;

  Eigen::MatrixXd left_times(const Eigen::MatrixXd& l) const;  // L P
  Eigen::MatrixXd solve(const Eigen::MatrixXd& r) const;       // P^-1 R
  Eigen::MatrixXd vectors() const;                              // P

  // P = Q X, Q = H_0 H_1 ... H_{m-3} with H_k = I - tau_k v_k v_k^T acting
  // on rows k + 1.. (column k of `reflectors` holds v_k there, leading 1);
  // no reflectors when used_inverse_iteration is false (Q = I).
  Eigen::MatrixXd reflectors;
  Eigen::VectorXd taus;
  Eigen::MatrixXd x;
  Eigen::PartialPivLU<Eigen::MatrixXd> x_lu;
};

// Throws std::runtime_error if the QR iteration does not converge.
PseudoEigen pseudo_eigen(const Eigen::MatrixXd& t);

// The eigenvector x of the upper Hessenberg matrix h for its eigenvalue
// lambda (accurate to round-off), by inverse iteration with the start vector
// of ones; false if three steps leave the backward error
// ||(h - lambda I) x|| / (||h||_1 ||x||) above 1e-12. x is scaled to unit
// largest entry.
bool hessenberg_eigenvector(const Eigen::MatrixXd& h, std::complex<double> lambda, Eigen::VectorXcd& x);

}  // namespace ambdiag::detail
