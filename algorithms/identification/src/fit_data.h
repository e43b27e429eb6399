// Shared pieces of the rational fit (private): the weighted data, the real
// pole basis, the linear start and the maximum-likelihood refinement.
#pragma once

#include <complex>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace ambdiag::detail {

using cd = std::complex<double>;

// Lines x entries; h already divided by (j w)^numerator_power.
struct FitData {
  Eigen::VectorXd w;       // rad/s
  Eigen::MatrixXcd h;      // lines x entries
  Eigen::MatrixXd weight;  // 1 / sigma, lines x entries
  int lines() const { return static_cast<int>(w.size()); }
  int entries() const { return static_cast<int>(h.cols()); }
};

// Number of real basis columns of a pole set: 2 per pair, 1 per real pole.
int basis_columns(const std::vector<cd>& poles);

// Complex basis at s = j w: for a pair p, columns 1/(s-p) + 1/(s-conj p) and
// j/(s-p) - j/(s-conj p) (real coefficients c1, c2 give the residue
// c1 + j c2); for a real pole, 1/(s-p); optionally a last column of ones.
Eigen::MatrixXcd pole_basis(const std::vector<cd>& poles, const Eigen::VectorXd& w, bool direct);

// Least squares through the normal equations of a tall real matrix A:
// (A^T A) x = b, Cholesky of the column-scaled Gram matrix (its condition is
// that of A squared; the scaled partial-fraction basis keeps it far from
// 1e16), with a pivoted QR of A^T A as the fallback. Several times faster
// than a Householder QR of A, and A^T A is what the Kaufman Jacobian needs.
class GramSolver {
 public:
  explicit GramSolver(const Eigen::MatrixXd& a);
  struct FromGram {};
  GramSolver(FromGram, const Eigen::MatrixXd& gram);  // from A^T A itself
  Eigen::MatrixXd solve(const Eigen::MatrixXd& b) const;

 private:
  void factor(const Eigen::MatrixXd& gram);
  Eigen::VectorXd scale_;
  Eigen::MatrixXd gram_;
  Eigen::MatrixXd chol_;
  bool ok_ = false;
};

// Derivatives of the basis functions with respect to the poles, for the
// Jacobian: a pair's model r/(s-p) + conj(r)/(s-conj p) with r = c1 + j c2
// has d/dRe p = c1 u1 + c2 u2 and d/dIm p = c1 u2 - c2 u1, where u1 =
// g + gc, u2 = j (g - gc), g = 1/(s-p)^2, gc = 1/(s-conj p)^2; a real pole
// has d/dp = c1 g. Columns in the order of pole_basis (lines x columns).
Eigen::MatrixXcd derivative_basis(const std::vector<cd>& poles, const Eigen::VectorXd& w);

// Residue of pole k from the real coefficients of its basis columns.
std::vector<cd> residues_from_coefficients(const std::vector<cd>& poles, const Eigen::VectorXd& c);

// Starting poles: `pairs` lightly damped pairs spread over [w_min, w_max].
std::vector<cd> starting_poles(int pairs, double w_min, double w_max);

// Relaxed vector fitting with common poles; returns the relocated poles
// (unstable ones flipped into the left half-plane).
std::vector<cd> vector_fit(const FitData& data, std::vector<cd> poles, int iterations);

// Weights that factor as weight(l, e) = a(l) b(e) (sigma of each entry a
// fixed multiple of a common line profile: constant sigma per entry, or such
// sigma scaled per line by the local residual). Then every entry's weighted
// least-squares problem has the same basis up to the factor b(e), and one
// Gram matrix of the pole basis serves all entries. Relative tolerance 1e-9.
bool separable_weights(const FitData& data, Eigen::VectorXd& a, Eigen::VectorXd& b);

// Real stacking [Re(diag(a) m); Im(diag(a) m)] of a lines x columns matrix.
Eigen::MatrixXd stack_lines(const Eigen::MatrixXcd& m, const Eigen::VectorXd& a);

// Weighted Gram matrices of one complex basis x (lines x n) for every
// column of w2 (lines x entries, squared weights): row e holds the upper
// triangle (column by column) of Re(x^H diag(w2(:, e)) x), which is A_e^T A_e
// of the real stacking A_e = [Re(w_e x); Im(w_e x)]. Computed as one blocked
// product of w2^T with the per-line products Re(conj x_li x_lj): real and
// imaginary rows merged per line, half the flops of stacking them per entry.
// With first_col > 0 only the columns j >= first_col of the triangle (the
// leading block is left out; unpacked as zeros).
Eigen::MatrixXd entry_grams(const Eigen::MatrixXcd& x, const Eigen::MatrixXd& w2, Eigen::Index first_col = 0);
Eigen::MatrixXd unpack_gram(const Eigen::Ref<const Eigen::VectorXd>& packed, Eigen::Index n, Eigen::Index first_col = 0);
// The same for a list of column pairs (i, j): E x pairs.
Eigen::MatrixXd entry_gram_pairs(const Eigen::MatrixXcd& x, const Eigen::MatrixXd& w2, const std::vector<std::pair<int, int>>& pairs);
// The imaginary counterpart, sum_l w(l, e) Im(conj x_li x_lj) for i < j
// (antisymmetric; strict upper triangle column by column), w any weights.
Eigen::MatrixXd entry_grams_imag(const Eigen::MatrixXcd& x, const Eigen::MatrixXd& w);

// Weighted least squares of every entry for a common basis phi (general
// weights): per-entry Gram factorizations, coefficients (columns x
// entries), weighted residuals weight .* (phi coef - h) and their cost.
struct EntrySystems {
  std::vector<GramSolver> gram;
  Eigen::MatrixXd coef;
  Eigen::MatrixXcd wresid;
  double cost = 0.0;
};
EntrySystems solve_entries(const FitData& data, const Eigen::MatrixXcd& phi);

struct LinearSolution {
  Eigen::MatrixXcd residues;  // entries x poles
  Eigen::VectorXd direct;     // entries
  double cost = 0.0;          // sum of squared weighted residuals
};
// Residues and direct terms for fixed poles (weighted least squares per entry).
LinearSolution solve_residues(const FitData& data, const std::vector<cd>& poles);

// The data seen through a pure delay tau: h e^{+j w tau}, so that a rational
// model of it is the rational part of H_meas = H_rat e^{-j w tau}.
FitData undelayed(const FitData& data, double delay_s);

struct MlSolution {
  std::vector<cd> poles;
  double delay_s = 0.0;   // estimated (fit_delay) or the fixed delay
  double delay_sd_s = 0.0;
  LinearSolution linear;
  Eigen::MatrixXd pole_covariance;  // of [Re p, Im p] per pair / [p] per real pole, unscaled (J^T J)^-1
  int iterations = 0;
  bool converged = false;
  std::string stop_reason;
};
// Levenberg-Marquardt on the poles (and the delay when fit_delay) with the
// residues projected out; `delay_s` is the start (or fixed) delay. Poles
// marked in `fixed` (per pole, may be empty) keep their place (their
// residues stay free); the covariance is then conditional on them.
MlSolution ml_refine(const FitData& data, std::vector<cd> poles, int max_iterations, bool fit_delay = false,
                     double delay_s = 0.0, const std::vector<bool>& fixed = {});

// Which output and input (indices) each fitted entry connects.
struct ModalStructure {
  int outputs = 0, inputs = 0;
  std::vector<int> output_of, input_of;  // per entry
};

struct PairRefit {
  cd poles[2];
  double cost = 0.0;              // weighted cost with modal residues for the pair
  Eigen::Matrix4d covariance;     // of [Re q1, Im q1, Re q2, Im q2], unscaled like MlSolution's
  Eigen::MatrixXcd residues;      // entries x 2: psi(o) l(i) of each pole
  int iterations = 0;
  bool ok = false;
};
// Maximum likelihood of poles k1, k2 with modal residues, r(o, i) =
// psi(o) l(i) per pole (a single mode of any linear system), the other
// poles fixed and their residues (free per entry) and the direct terms
// projected out; Levenberg-Marquardt on the two poles and psi, l together,
// started from the best rank-one approximation of `residues` (entries x
// poles). Data undelayed.
PairRefit refit_pair_rank_one(const FitData& data, const std::vector<cd>& poles, const Eigen::MatrixXcd& residues, size_t k1, size_t k2,
                              const ModalStructure& modal, int max_iterations);

// Score statistic of a delay at `delay_s`: 2 x the cost decrease that one
// Gauss-Newton step in (poles, delay) predicts; chi^2 with 1 degree of
// freedom (in units of the noise) when the delay is right.
double delay_score(const FitData& data, const std::vector<cd>& poles, double delay_s);

}  // namespace ambdiag::detail
