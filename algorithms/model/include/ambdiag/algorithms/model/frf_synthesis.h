// Compliance FRF matrix of a plant model: H[o][i](f) = x_o / f_i in m/N for
// every sensor o and actuator i, at any frequency grid.
//
// Lateral entries come from the rotor system (rotor_system.h), computed
//  - direct: x = Cout (K - w^2 M + j w C)^-1 B f per line, with a sparse
//    complex LU (KLU; symbolic analysis once, numeric factorization per
//    line) and the low-rank structural damping added by the Woodbury
//    identity, cost per line linear in the number of elements for a shaft;
//    when C_s has rank above a quarter of a small system (all free-free
//    modes damped) a dense complex LU per line is cheaper and is used;
//  - modal: superposition over eigenvalues of the first-order form,
//    H(w) = sum_k (Cs v_k)(u_k^T Bs) / (j w - lambda_k). With every
//    eigenvalue (dense eigen-decomposition, O(n^3) once) it is exact up to
//    round-off; with a Krylov basis (ModalBasis::krylov) it sums the modes
//    of the band that the inputs excite plus Ritz values beyond the band
//    that stand in for the rest, grown until the relative residual on
//    every line is below krylov_tol (rotor_krylov.h), at a cost linear in
//    the model size.
// Housing resonances add 1 / (m (w0^2 - w^2 + 2 j zeta w0 w)) to every entry
// whose sensor and actuator share its plane and direction; the axial entry is
// 1 / (k - w^2 m + j w c) plus the axial housings; lateral-axial entries are 0.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "ambdiag/algorithms/model/rotor_system.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag {

enum class FrfMethod { direct, modal };
// automatic: a Krylov basis; for up to 400 states every eigenvalue when the
// basis does not reach krylov_tol on every line.
enum class ModalBasis { automatic, all, krylov };

struct FrfSynthesisOptions {
  FrfMethod method = FrfMethod::direct;
  ModalBasis modal_basis = ModalBasis::automatic;
  double krylov_tol = 1e-8;
  // Which free-free modes carry the structural damping; its omega_max is set
  // from the highest line of the grid.
  StructuralDampingOptions damping = {};
};

// What a synthesis did and where the time went.
struct FrfReport {
  std::string method;  // e.g. "direct, dense LU per line", "modal, Krylov basis"
  int damping_modes_per_plane = 0;
  double damping_cutoff_hz = std::numeric_limits<double>::infinity();
  int poles = 0;             // modal: terms summed
  int poles_in_band = 0;     // modal: of those, |lambda| <= the highest line
  int krylov_size = 0;
  double krylov_residual = 0.0;  // largest relative residual over the lines
  bool converged = true;     // Krylov: residual below krylov_tol on every line
  double assembly_s = 0.0;   // rotor assembly incl. free-free modes
  double setup_s = 0.0;      // factorization, eigen-decomposition or Krylov basis
  double lines_s = 0.0;      // work per line (solves, or evaluating the sum)
};

// Throws InputError if the model has no sensors or actuators, a frequency is
// not finite and > 0, or the model is singular.
FrfData synthesize_frf(const PlantModel& plant, double speed_rpm, const std::vector<double>& freq_hz,
                       const FrfSynthesisOptions& options = {}, FrfReport* report = nullptr);

// Evenly spaced grid fmin, fmin + df, ... <= fmax (+ half a step of slack).
std::vector<double> frequency_grid(double fmin_hz, double fmax_hz, double df_hz);

}  // namespace ambdiag
