#include "ambdiag/algorithms/model/rotor_system.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "ambdiag/core/error.h"
#include "beam_element.h"

namespace ambdiag {

namespace {

using Triplets = std::vector<Eigen::Triplet<double>>;

// Per-plane DOF offsets inside a node's four lateral DOFs. The x-z plane uses
// (x, ty) with theta = ty; the y-z plane uses (y, tx) with theta = -tx.
constexpr int kXPlane[2] = {0, 3};
constexpr int kYPlane[2] = {1, 2};
constexpr double kYSign[2] = {1.0, -1.0};

// Adds a 4x4 plane matrix of element (i, i+1) to both planes.
void add_both_planes(Triplets& t, int node, const detail::Matrix4& a) {
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      const int nr = node + r / 2, nc = node + c / 2;
      t.emplace_back(4 * nr + kXPlane[r % 2], 4 * nc + kXPlane[c % 2], a(r, c));
      t.emplace_back(4 * nr + kYPlane[r % 2], 4 * nc + kYPlane[c % 2], kYSign[r % 2] * kYSign[c % 2] * a(r, c));
    }
  }
}

// Gyroscopic coupling of a plane rotary-inertia matrix R_p (polar): with
// tx = -N T q_y and ty = N q_x, G_yx = -T R_p and G_xy = R_p T.
void add_gyroscopic(Triplets& t, int node, const detail::Matrix4& rp) {
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      const int nr = node + r / 2, nc = node + c / 2;
      t.emplace_back(4 * nr + kYPlane[r % 2], 4 * nc + kXPlane[c % 2], -kYSign[r % 2] * rp(r, c));
      t.emplace_back(4 * nr + kXPlane[r % 2], 4 * nc + kYPlane[c % 2], rp(r, c) * kYSign[c % 2]);
    }
  }
}

// Embeds a plane mode (w, theta per node) in the full lateral DOFs.
void embed_plane_mode(const Eigen::VectorXd& phi, bool y_plane, Eigen::Ref<Eigen::VectorXd> out) {
  const int nodes = static_cast<int>(phi.size()) / 2;
  out.setZero();
  for (int n = 0; n < nodes; ++n) {
    const auto& dofs = y_plane ? kYPlane : kXPlane;
    out(4 * n + dofs[0]) = phi(2 * n);
    out(4 * n + dofs[1]) = (y_plane ? -1.0 : 1.0) * phi(2 * n + 1);
  }
}

// Whether C_s uses every free-free mode (the definition) or a band.
bool all_damping_modes(const PlantModel& p, const StructuralDampingOptions& o) {
  using Modes = StructuralDampingOptions::Modes;
  const int plane_dofs = 2 * p.node_count();
  const bool have_band = o.omega_max_rad_per_s > 0.0 && std::isfinite(o.omega_max_rad_per_s);
  if (o.modes == Modes::band && !have_band) {
    throw InputError("structural damping: a band of modes needs the highest frequency of interest");
  }
  if (o.modes == Modes::band && !(o.band_factor >= 1.0)) throw InputError("structural damping: band_factor must be >= 1");
  const bool all = o.modes == Modes::all ||
                   (o.modes == Modes::automatic && (plane_dofs <= o.all_modes_max_plane_dofs || !have_band));
  // Every mode of a plane means a dense eigenproblem and a dense C_s.
  constexpr int kMaxAllModesPlaneDofs = 2000;
  if (all && plane_dofs > kMaxAllModesPlaneDofs) {
    throw InputError("structural_damping: " + std::to_string(p.shaft.size()) +
                     " shaft elements are too many to damp every free-free mode; give a highest frequency of "
                     "interest (f_max) so that the modes in a band carry it");
  }
  return all;
}

}  // namespace

int lateral_dof(int node, char dir) {
  switch (dir) {
    case 'x': return 4 * node;
    case 'y': return 4 * node + 1;
    case 'a': return 4 * node + 2;
    case 'b': return 4 * node + 3;
    default: throw InputError(std::string("unknown lateral direction '") + dir + "'");
  }
}

Eigen::RowVectorXd RotorSystem::dof_row(int full_dof) const {
  if (reduced()) return basis.row(full_dof);
  Eigen::RowVectorXd r = Eigen::RowVectorXd::Zero(size());
  r(full_dof) = 1.0;
  return r;
}

Eigen::MatrixXd RotorSystem::dense_damping() const {
  Eigen::MatrixXd d = Eigen::MatrixXd(c);
  if (damping_d.size() > 0) d += damping_u * damping_d.asDiagonal() * damping_u.transpose();
  return d;
}

Eigen::MatrixXd first_order_matrix(const RotorSystem& sys) {
  const int n = sys.size();
  Eigen::LDLT<Eigen::MatrixXd> mf{Eigen::MatrixXd(sys.m)};
  if (mf.info() != Eigen::Success || mf.vectorD().minCoeff() <= 0.0) {
    throw InputError("mass matrix is not positive definite (negative or missing mass?)");
  }
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  a.topRightCorner(n, n).setIdentity();
  a.bottomLeftCorner(n, n) = -mf.solve(Eigen::MatrixXd(sys.k));
  a.bottomRightCorner(n, n) = -mf.solve(sys.dense_damping());
  return a;
}

RotorSystem assemble_rotor(const PlantModel& p, double speed_rpm, const StructuralDampingOptions& damping) {
  validate_plant(p);
  const int nodes = p.node_count();
  const int n = 4 * nodes;
  const double omega = speed_rpm * 2.0 * std::numbers::pi / 60.0;

  Triplets tm, tk, tc;
  for (size_t i = 0; i < p.shaft.size(); ++i) {
    const auto& e = p.shaft[i];
    const auto& mat = p.materials.at(e.material);
    const int node = static_cast<int>(i);
    add_both_planes(tk, node, detail::beam_stiffness(e, mat));
    add_both_planes(tm, node, detail::beam_translational_mass(e, mat) + detail::beam_rotary_mass(e, mat));
    if (omega != 0.0) add_gyroscopic(tc, node, 2.0 * omega * detail::beam_rotary_mass(e, mat));
  }
  for (const auto& d : p.disks) {
    for (char dir : {'x', 'y'}) tm.emplace_back(lateral_dof(d.node, dir), lateral_dof(d.node, dir), d.m_kg);
    for (char dir : {'a', 'b'}) tm.emplace_back(lateral_dof(d.node, dir), lateral_dof(d.node, dir), d.id_kg_m2);
    tc.emplace_back(lateral_dof(d.node, 'a'), lateral_dof(d.node, 'b'), omega * d.ip_kg_m2);
    tc.emplace_back(lateral_dof(d.node, 'b'), lateral_dof(d.node, 'a'), -omega * d.ip_kg_m2);
  }
  // Structural damping is defined on the free-free rotor (shaft and disks, no
  // links): keep its mass matrix so that C_s = M0 Phi diag Phi^T M0 leaves the
  // rigid-body modes undamped.
  Eigen::SparseMatrix<double> m0(n, n);
  m0.setFromTriplets(tm.begin(), tm.end());
  for (const auto& l : p.links) {
    const LinkCoefficients v = l.at_speed(speed_rpm);
    const int dx = lateral_dof(l.node, 'x'), dy = lateral_dof(l.node, 'y');
    const int rows[2] = {dx, dy};
    for (int a = 0; a < 2; ++a)
      for (int b = 0; b < 2; ++b) {
        const int off = 2 * a + b;  // xx, xy, yx, yy
        tk.emplace_back(rows[a], rows[b], v[static_cast<size_t>(off)]);
        tc.emplace_back(rows[a], rows[b], v[static_cast<size_t>(4 + off)]);
        tm.emplace_back(rows[a], rows[b], v[static_cast<size_t>(8 + off)]);
      }
  }
  Eigen::SparseMatrix<double> m(n, n), k(n, n), c(n, n);
  m.setFromTriplets(tm.begin(), tm.end());
  k.setFromTriplets(tk.begin(), tk.end());
  c.setFromTriplets(tc.begin(), tc.end());

  RotorSystem s;
  s.full_dof_count = n;
  s.speed_rad_per_s = omega;

  const bool modal_damping = p.structural_damping.kind == StructuralDamping::Kind::modal && p.structural_damping.zeta > 0;
  const bool reduce = p.reduction.kind == Reduction::Kind::modal;
  if (!modal_damping && !reduce) {
    s.m = std::move(m);
    s.k = std::move(k);
    s.c = std::move(c);
    return s;
  }

  PlaneModeOptions po;
  if (reduce) {
    po.max_elastic = p.reduction.n_elastic_modes;
  } else if (!all_damping_modes(p, damping)) {
    po.omega_max_rad_per_s = damping.band_factor * damping.omega_max_rad_per_s;
    s.damping_cutoff_rad_per_s = po.omega_max_rad_per_s;
  }
  const PlaneModes pm = free_free_plane_modes(p, po);
  const int nm = static_cast<int>(pm.omega_rad_per_s.size());
  // Full-DOF shapes of both planes: columns [x-plane modes, y-plane modes].
  Eigen::MatrixXd phi(n, 2 * nm);
  for (int i = 0; i < nm; ++i) {
    embed_plane_mode(pm.shapes.col(i), false, phi.col(i));
    embed_plane_mode(pm.shapes.col(i), true, phi.col(nm + i));
  }
  // C_s = M Phi diag(2 zeta w) Phi^T M over elastic modes (rigid-body: none).
  Eigen::VectorXd d = Eigen::VectorXd::Zero(2 * nm);
  if (modal_damping) {
    s.damping_modes_per_plane = std::max(0, nm - 2);
    for (int i = 2; i < nm; ++i) {
      d(i) = d(nm + i) = 2.0 * p.structural_damping.zeta * pm.omega_rad_per_s(i);
    }
  }
  if (reduce) {
    // The reduced coordinates are the free-free modes (M-normalised), so
    // Phi^T M Phi = I and C_s becomes diag(d) in these coordinates.
    s.basis = phi;
    s.m = (phi.transpose() * (m * phi)).sparseView();
    s.k = (phi.transpose() * (k * phi)).sparseView();
    Eigen::MatrixXd cr = phi.transpose() * (c * phi);
    cr.diagonal() += d;
    s.c = cr.sparseView();
    return s;
  }
  s.m = std::move(m);
  s.k = std::move(k);
  s.c = std::move(c);
  if (modal_damping) {
    s.damping_u = m0 * phi;
    s.damping_d = d;
  }
  return s;
}

}  // namespace ambdiag
