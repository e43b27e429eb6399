// A sum over the poles of a real system, evaluated in real arithmetic
// (private to the FRF synthesis).
//
// A real matrix D in pseudo-eigenvalue form (Eigen's EigenSolver: 1 x 1
// blocks d and 2 x 2 blocks [u v; -v u] for the pair u +- jv) with real
// left and right factors L (rows x m) and R (m x inputs) gives, for complex
// scalars alpha, beta per line,
//   H(line) = L (alpha I - beta D)^-1 R.
// A pair contributes e (L1 R1 + L2 R2) + f (L1 R2 - L2 R1) with
//   e = (alpha - beta u) / det,  f = beta v / det,
//   det = (alpha - beta u)^2 + (beta v)^2,
// so each line costs one complex division per pair and a real-by-complex
// product per residue entry: half the arithmetic of summing both poles of
// the pair in complex arithmetic. Kernel and product are vector kernels
// over chunks of lines (AVX2/FMA where the CPU has it, vector_kernels.h).
#pragma once

#include <Eigen/Core>

namespace ambdiag::detail {

class PoleSum {
 public:
  // eigenvalues: those of D in Eigen's order (a pair is adjacent, u + jv
  // first); left: rows x m; right: m x inputs.
  PoleSum(const Eigen::VectorXcd& eigenvalues, const Eigen::MatrixXd& left, const Eigen::MatrixXd& right);

  Eigen::Index poles() const { return eigenvalues_.size(); }
  // lines x (rows * inputs), column r * inputs + i: entry (r, i) of H. The
  // lines go in chunks whose kernel stays in cache.
  Eigen::MatrixXcd evaluate(const Eigen::VectorXcd& alpha, const Eigen::VectorXcd& beta) const;

 private:
  Eigen::VectorXcd eigenvalues_;
  Eigen::MatrixXd residues_;  // m x (rows * inputs)
};

}  // namespace ambdiag::detail
