// The lateral rotor model assembled from a plant model at one speed:
//
//   M q'' + (C + Omega G + C_s) q' + K q = B f,     x = Cout q
//
// with q the lateral DOFs (x, y, tx, ty per node, dx/dz = ty, dy/dz = -tx),
// Omega the spin in rad/s, G the skew-symmetric gyroscopic matrix, links added
// as f = -(K q + C q' + M q'') at their node, and C_s the modal structural
// damping of the free-free rotor, kept in low-rank form U diag(d) U^T. With a
// modal reduction the coordinates are those of the reduced basis
// (q_full = T q); otherwise T is empty and q are the FE DOFs.
#pragma once

#include <limits>
#include <string>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "ambdiag/core/plant_model.h"

namespace ambdiag {

// Index of a lateral DOF: dir 'x', 'y' (displacements) or 'a' (tx), 'b' (ty).
int lateral_dof(int node, char dir);

// Which free-free elastic modes carry the modal structural damping
// C_s = M0 Phi diag(2 zeta w_i) Phi^T M0.
//
// `all` is the definition of the plant model page; it needs every mode of a
// plane (a dense eigenproblem, O(plane DOFs^3)) and makes C_s dense, so it is
// only cheap for small models. `band` keeps the elastic modes with
// w_i <= band_factor * w_max, w_max the highest frequency the caller asks for
// (FRF grid, modal f_max). A dropped mode i responds quasi-statically in the
// band: its damping force relative to its elastic force is 2 zeta w / w_i
// <= 2 zeta / band_factor (1.5e-3 for zeta = 0.0075 and the default factor
// 10), in quadrature, so dropping it changes that mode's contribution to any
// FRF by at most that fraction in phase and its square in magnitude.
// `automatic`: all modes when a plane has at most all_modes_max_plane_dofs
// DOFs or when the caller gives no band, else band.
struct StructuralDampingOptions {
  enum class Modes { automatic, all, band };
  Modes modes = Modes::automatic;
  double band_factor = 10.0;
  int all_modes_max_plane_dofs = 200;  // 99 shaft elements
  // Highest frequency of interest, rad/s; 0 = not given. Set by the FRF
  // synthesis and the modal analysis from the user's request.
  double omega_max_rad_per_s = 0.0;
};

struct RotorSystem {
  Eigen::SparseMatrix<double> m;  // mass, kg
  Eigen::SparseMatrix<double> c;  // damping incl. Omega G and links, N s/m
  Eigen::SparseMatrix<double> k;  // stiffness, N/m
  Eigen::MatrixXd damping_u;      // structural damping C_s = U diag(d) U^T
  Eigen::VectorXd damping_d;
  Eigen::MatrixXd basis;          // reduction T (full DOFs x coordinates); empty: none
  int full_dof_count = 0;
  double speed_rad_per_s = 0.0;
  // Elastic free-free modes per plane that carry C_s, and the cutoff used
  // (infinite: all modes).
  int damping_modes_per_plane = 0;
  double damping_cutoff_rad_per_s = std::numeric_limits<double>::infinity();

  int size() const { return static_cast<int>(m.rows()); }
  bool reduced() const { return basis.size() > 0; }
  // Row that maps coordinates to one full DOF (a unit row when not reduced).
  Eigen::RowVectorXd dof_row(int full_dof) const;
  // Dense total damping (C + C_s) for small systems.
  Eigen::MatrixXd dense_damping() const;
};

// Undamped modes of the free-free rotor at standstill in one bending plane
// (DOFs w, theta per node; same for x-z and y-z planes), mass-normalised,
// ascending; the first two are the rigid-body modes (omega set to 0).
struct PlaneModes {
  Eigen::VectorXd omega_rad_per_s;
  Eigen::MatrixXd shapes;  // (2 * nodes) x modes
  // How they were found: "dense" or "lanczos"; Lanczos steps; whether a
  // Sturm count (inertia of K - tau M) confirmed that no mode below the
  // last one returned was missed.
  std::string solver;
  int iterations = 0;
  bool sturm_checked = false;
};

// Which plane modes to compute. The elastic modes returned are those with
// w <= omega_max_rad_per_s, at most max_elastic of them (-1: no limit).
//  - dense: generalized symmetric eigenproblem of the whole plane,
//    O(DOFs^3); all modes.
//  - lanczos: Lanczos with full reorthogonalisation in the M inner product
//    on K^+ M (K grounded at the two end translations and solved by sparse
//    LDL^T, O(DOFs) for a shaft; the two rigid-body modes are known and
//    deflated exactly), stopped when every wanted Ritz pair has a relative
//    residual below 1e-10 and a Sturm count confirms the number of modes.
//  - automatic: dense up to 400 plane DOFs or when every mode is asked
//    for, else lanczos.
struct PlaneModeOptions {
  enum class Solver { automatic, dense, lanczos };
  Solver solver = Solver::automatic;
  int max_elastic = -1;
  double omega_max_rad_per_s = std::numeric_limits<double>::infinity();
};
PlaneModes free_free_plane_modes(const PlantModel& plant, const PlaneModeOptions& options);
// The first `count` modes including the two rigid-body ones; `count` < 0: all.
PlaneModes free_free_plane_modes(const PlantModel& plant, int count = -1);

// The first-order (state-space) matrix [0 I; -M^-1 K  -M^-1 (C + C_s)] of a
// system, dense. Throws InputError if M is not positive definite.
Eigen::MatrixXd first_order_matrix(const RotorSystem& sys);

// Assembles the lateral system at `speed_rpm` (links from their speed
// tables). Throws InputError if the model is singular or unphysical, or if
// structural damping needs a band that `damping` does not give.
RotorSystem assemble_rotor(const PlantModel& plant, double speed_rpm, const StructuralDampingOptions& damping = {});

}  // namespace ambdiag
