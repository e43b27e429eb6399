// Modal analysis of a plant model at one speed.
//
// Lateral rotor modes are the eigenvalues lambda of the first-order form
//   [0 I; -M^-1 K  -M^-1 (C + Omega G + C_s)],
// reported as f_hz = |lambda| / 2 pi, zeta = -Re(lambda) / |lambda|, one
// mode per complex-conjugate pair (Im lambda > 0); real eigenvalues are
// overdamped modes. Whirl from the mode shape: with complex amplitudes X, Y
// of a node, the forward circular part is |X + jY| / 2 and the backward
// part |X - jY| / 2; fwd_fraction sums their squares over the nodes.
// Housing resonances (in parallel) and the decoupled axial model add
// their modes in closed form.
#pragma once

#include <complex>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ambdiag/algorithms/model/rotor_system.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag {

enum class Whirl { forward, backward, none };
std::string to_string(Whirl w);

struct Mode {
  double f_hz = 0.0;       // undamped natural frequency |lambda| / 2 pi
  double zeta = 0.0;       // damping ratio -Re(lambda) / |lambda|
  std::complex<double> eigenvalue;  // rad/s
  std::string direction;   // "radial" or "axial"
  std::string kind;        // "rotor", "housing", "axial", "axial_housing"
  Whirl whirl = Whirl::none;
  double fwd_fraction = 0.0;
  bool overdamped = false;  // real eigenvalue
  std::string label;        // e.g. "housing_A", "axial rigid body"
  Eigen::VectorXcd shape;   // lateral rotor modes: full DOF shape (x, y, tx, ty per node), max |x|,|y| = 1
  // Log decrement 2 pi zeta / sqrt(1 - zeta^2) (infinite when overdamped).
  double log_decrement() const;
};

// How the lateral rotor eigenvalues are found:
//  - dense: every eigenvalue of the balanced first-order form (2n states),
//    O(n^3): exact up to round-off, for small models;
//  - krylov: the eigenvalues with |lambda| <= 2 pi f_max_hz by shift-invert
//    block Arnoldi on the first-order form (rotor_krylov.h: one sparse
//    factorization of K + sigma C + sigma^2 M at a real shift sigma =
//    -pi f_max, full reorthogonalisation, relative Ritz residuals below
//    1e-10); cost linear in the number of elements for a shaft. Chosen over
//    a reduced basis of free-free modes because its accuracy does not
//    depend on how strongly links and gyroscopics couple those modes: it
//    converges to the eigenvalues of the full model and says how well.
//  - automatic: krylov when f_max_hz is finite and the model has more than
//    400 states, else dense.
enum class ModalSolver { automatic, dense, krylov };

struct ModalOptions {
  bool overdamped = true;  // also report real (overdamped) rotor eigenvalues
  bool shapes = true;      // keep mode shapes
  // Highest frequency of interest, Hz. The dense solver reports every mode
  // anyway; the Krylov solver reports the lateral rotor modes up to it and
  // needs it finite. It also sets the band of the structural damping.
  double f_max_hz = std::numeric_limits<double>::infinity();
  ModalSolver solver = ModalSolver::automatic;
  StructuralDampingOptions damping = {};  // its omega_max is set from f_max_hz
};

struct ModalResult {
  double speed_rpm = 0.0;
  std::vector<Mode> modes;  // ascending f_hz
  // Report: "dense" or "krylov"; Krylov basis size, the largest relative
  // Ritz residual of the modes returned (0 for dense) and whether every
  // Ritz value that can lie in the band converged (false: the basis hit its
  // limit of 1000 vectors; the modes returned are still those found).
  std::string solver;
  int krylov_size = 0;
  double max_residual = 0.0;
  bool converged = true;
  int damping_modes_per_plane = 0;
};

// Throws InputError for a bad speed or model, or when a model too large for
// the dense solver comes without f_max_hz.
ModalResult modal_analysis(const PlantModel& plant, double speed_rpm, const ModalOptions& options = {});

}  // namespace ambdiag
