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

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "ambdiag/core/plant_model.h"

namespace ambdiag {

// Index of a lateral DOF: dir 'x', 'y' (displacements) or 'a' (tx), 'b' (ty).
int lateral_dof(int node, char dir);

struct RotorSystem {
  Eigen::SparseMatrix<double> m;  // mass, kg
  Eigen::SparseMatrix<double> c;  // damping incl. Omega G and links, N s/m
  Eigen::SparseMatrix<double> k;  // stiffness, N/m
  Eigen::MatrixXd damping_u;      // structural damping C_s = U diag(d) U^T
  Eigen::VectorXd damping_d;
  Eigen::MatrixXd basis;          // reduction T (full DOFs x coordinates); empty: none
  int full_dof_count = 0;
  double speed_rad_per_s = 0.0;

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
};
// `count` < 0: all modes.
PlaneModes free_free_plane_modes(const PlantModel& plant, int count = -1);

// The first-order (state-space) matrix [0 I; -M^-1 K  -M^-1 (C + C_s)] of a
// system, dense. Throws InputError if M is not positive definite.
Eigen::MatrixXd first_order_matrix(const RotorSystem& sys);

// Assembles the lateral system at `speed_rpm` (links from their speed
// tables). Throws InputError if the model is singular or unphysical.
RotorSystem assemble_rotor(const PlantModel& plant, double speed_rpm);

}  // namespace ambdiag
