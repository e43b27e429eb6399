// Receptance of a lateral rotor system between any of its full DOFs,
//
//   G(w) = (K - w^2 M + j w (C + C_s))^-1,   G[u, v] = x_u / f_v,
//
// from every eigenvalue of the first-order form (one dense eigen-
// decomposition, frf_modal.cc), so that any block G[rows, cols] on every line
// costs one pole sum (frf_pole_sum.h): O(lines x poles x rows x cols), no
// solve. Used for exact low-rank updates (Woodbury) of the FRF under a change
// confined to a few DOFs (explain's screening). For the domains above
// model, not for the server or the CLI (hence namespace detail).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "ambdiag/algorithms/model/rotor_system.h"

namespace ambdiag::detail {

// The real pseudo-modal factors of a rotor system: with D block diagonal
// (Eigen's pseudo-eigenvalue form), G[u, v](s) = top_u (s I - D)^-1 right_v,
// top = dof_row * P_top, right = P^-1 [0; M^-1 dof_row^T].
struct ModalFactors {
  Eigen::VectorXcd eigenvalues;
  Eigen::MatrixXd top;    // coordinates x states: displacement rows of P (balanced)
  Eigen::MatrixXd right;  // states x coordinates: P^-1 [0; M^-1] (balanced)
};
// Throws InputError when the eigenproblem fails.
ModalFactors modal_factors(const RotorSystem& sys);

class RotorReceptance {
 public:
  RotorReceptance(const RotorSystem& sys, const std::vector<double>& omega_rad_per_s);
  // lines x (rows.size() * cols.size()); column r * cols.size() + c is G[rows[r], cols[c]].
  Eigen::MatrixXcd block(const std::vector<int>& rows, const std::vector<int>& cols) const;
  int lines() const { return static_cast<int>(jw_.size()); }

 private:
  RotorSystem sys_;
  ModalFactors f_;
  Eigen::VectorXcd jw_;
};

}  // namespace ambdiag::detail
