// Shift-invert Krylov machinery for large rotor systems (private to the
// algorithms library): the eigenvalues of a band and a reduced model for
// FRFs, at a cost linear in the number of elements for a shaft.
//
// The first-order form x' = A x, x = [q; v], A = [0 I; -M^-1 K  -M^-1 C_t]
// (C_t = C + U diag(d) U^T), with the velocity scaled by s (x = [q; v / s],
// a similarity transform that balances the two halves in the band) and a
// real shift sigma, has the operator
//   Op = (A_s - sigma I)^-1:  Op [b1; b2] = [x1; (b1 + sigma x1) / s],
//   P(sigma) x1 = -s M b2 - (C_t + sigma M) b1,  P(sigma) = K + sigma C_t + sigma^2 M,
// so every application is one solve with a sparse real factorization of
// P(sigma) (KLU, computed once), the low-rank C_s entering by the Woodbury
// identity (up to 200 DOFs: one dense LU of P(sigma) with C_s in it). An
// eigenvalue theta of Op is an eigenvalue lambda = sigma + 1 / theta of A:
// the modes nearest the shift have the largest theta and a Krylov space of
// Op finds them first (Ericsson & Ruhe 1980; Saad,
// Numerical Methods for Large Eigenvalue Problems, 2nd ed. 2011, ch. 6-7).
// Block Arnoldi with full reorthogonalisation keeps the basis orthonormal to
// round-off, and a block of p vectors finds eigenvalues of multiplicity up
// to p (an isotropic rotor at standstill has every eigenvalue twice).
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Core>
#include <Eigen/LU>

#include "ambdiag/algorithms/model/rotor_system.h"
#include "frf_terms.h"
#include "klu_complex.h"

namespace ambdiag::detail {

class ShiftInvert {
 public:
  // Factorizes P(sigma). ok() is false if it is (numerically) singular,
  // e.g. sigma on an overdamped eigenvalue.
  ShiftInvert(const RotorSystem& sys, double sigma, double scale);
  bool ok() const { return ok_; }
  Eigen::Index state_size() const { return 2 * n_; }
  double sigma() const { return sigma_; }
  double scale() const { return scale_; }
  // Op X for scaled states X (2n x cols).
  Eigen::MatrixXd apply(const Eigen::MatrixXd& x) const;
  // Op B_s for forces f (n x cols): B_s = [0; M^-1 f / s].
  Eigen::MatrixXd apply_to_forces(const Eigen::MatrixXd& f) const;

 private:
  Eigen::MatrixXd solve(Eigen::MatrixXd rhs) const;  // P(sigma)^-1 rhs
  Eigen::MatrixXd damping_times(const Eigen::MatrixXd& x) const;  // C_t x

  const RotorSystem& sys_;
  Eigen::Index n_ = 0;
  double sigma_ = 0.0, scale_ = 1.0;
  bool ok_ = false;
  // Small systems: dense LU of P(sigma) (C_s included) and C_t + sigma M.
  bool dense_ = false;
  Eigen::PartialPivLU<Eigen::MatrixXd> dense_lu_;
  Eigen::MatrixXd ct_sigma_m_;
  // Large systems: KLU of P0 and Woodbury for C_s.
  std::unique_ptr<KluReal> lu_;
  Eigen::MatrixXd u_;    // structural damping columns with d > 0
  Eigen::VectorXd d_;
  Eigen::MatrixXd p0u_;  // P0^-1 U, P0 = P(sigma) without C_s
  Eigen::PartialPivLU<Eigen::MatrixXd> capacitance_;  // (sigma D)^-1 + U^T P0^-1 U
};

// Block Arnoldi: Op V_m = V_{m+p} H with V orthonormal (classical
// Gram-Schmidt, twice). A block column that loses rank is replaced by a
// random orthogonal direction with a zero coefficient, so the relation
// stays exact and the block size constant.
class BlockArnoldi {
 public:
  // `start` (N x p) is the first block: start = V_1 beta.
  BlockArnoldi(const ShiftInvert& op, const Eigen::MatrixXd& start, unsigned seed);
  // Adds a block; false if the space has no room for another.
  bool extend();
  int size() const { return m_; }
  int block() const { return p_; }
  // The basis V_m (first m columns) and the next block.
  const Eigen::MatrixXd& vectors() const { return v_; }
  // T = V_m^T Op V_m (m x m) and F (p x p), the coupling of the last block
  // to the next: Op V_m = V_m T + V_next F E_last^T.
  Eigen::MatrixXd projected() const { return h_.topLeftCorner(m_, m_); }
  Eigen::MatrixXd coupling() const { return h_.block(m_, m_ - p_, p_, p_); }
  const Eigen::MatrixXd& start_coefficients() const { return beta_; }

 private:
  // Orthonormalises the columns of w against V(:, 0:k) and each other;
  // returns the coefficients of w in the new columns (upper triangular).
  Eigen::MatrixXd orthonormalize(Eigen::MatrixXd& w, int k);

  const ShiftInvert& op_;
  int p_ = 0, m_ = 0;
  Eigen::MatrixXd v_, h_, beta_;
  unsigned seed_;
};

// Eigenvalues of a band, with right vectors.
struct BandModes {
  Eigen::VectorXcd eigenvalues;  // rad/s, |lambda| <= the band; both members of a pair
  Eigen::MatrixXcd shapes;       // coordinates x modes (q of the system)
  int krylov_size = 0;
  double max_residual = 0.0;     // largest relative Ritz residual among those returned
  bool converged = false;
};

// All eigenvalues with |lambda| <= omega_band_rad_per_s (shift at -omega/2,
// random start block of 4, stopped when every Ritz value that can be in
// the band has a relative residual below 1e-10 and their count is steady).
BandModes rotor_modes_in_band(const RotorSystem& sys, double omega_band_rad_per_s, bool shapes);

// The lateral FRF of a reduced model (frf_lateral.h,
// lateral_frf_modal_krylov) is a one-sided block rational Krylov projection
// at a real shift sigma = -w_max / 2 started at Op B_s (Grimme 1997): it
// matches H and its first moments at sigma and holds every mode of the
// band that the inputs excite; its Ritz values beyond the band stand in for
// the rest. With T = P D P^-1 in real pseudo-eigen form (D block diagonal,
// frf_pole_sum.h) and z = P^-1 E_1 beta,
//   H(s) = -Cout V P (I - (s - sigma) D)^-1 z,
// a sum over poles lambda_i = sigma + 1 / theta_i costing O(basis x
// entries) per line in real arithmetic. The basis grows until the relative residual of the
// reduced solve, |s - sigma| ||F E_last^T y(s)|| / ||beta||, is below the
// tolerance on every line.

}  // namespace ambdiag::detail
