// Move-only owner of a KLU factorization of a complex sparse matrix
// (SuiteSparse KLU, Davis & Palamadai Natarajan 2010), for many matrices
// with one pattern: symbolic analysis once, numeric refactorization per
// matrix (pivot order reused), with a full factorization when the reused
// pivots lose accuracy. Every KLU return code is checked here.
#pragma once

#include <complex>
#include <memory>

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace ambdiag::detail {

class KluComplex {
 public:
  using Matrix = Eigen::SparseMatrix<std::complex<double>, Eigen::ColMajor, int>;

  // Analyses the pattern of `pattern` (compressed). The matrix must keep
  // this pattern in every factorize call.
  explicit KluComplex(const Matrix& pattern);
  ~KluComplex();
  KluComplex(KluComplex&&) noexcept;
  KluComplex& operator=(KluComplex&&) noexcept;
  KluComplex(const KluComplex&) = delete;
  KluComplex& operator=(const KluComplex&) = delete;

  // Factorizes `a`; false if it is singular.
  bool factorize(const Matrix& a);
  // Solves A X = B in place (B: rows x nrhs, column-major).
  void solve_in_place(Eigen::MatrixXcd& b) const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// The same for one real matrix: one factorization, many solves.
class KluReal {
 public:
  using Matrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

  // Analyses and factorizes `a` (compressed). Throws std::runtime_error on a
  // KLU failure other than singularity.
  explicit KluReal(const Matrix& a);
  ~KluReal();
  KluReal(KluReal&&) noexcept;
  KluReal& operator=(KluReal&&) noexcept;
  KluReal(const KluReal&) = delete;
  KluReal& operator=(const KluReal&) = delete;

  // Reciprocal pivot ratio of the factorization (KLU's rcond); 0 if singular.
  double rcond() const;
  // Solves A X = B in place; B column-major.
  void solve_in_place(Eigen::MatrixXd& b) const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace ambdiag::detail
