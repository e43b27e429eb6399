#include "ambdiag/algorithms/model/modal_analysis.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include "ambdiag/algorithms/model/rotor_system.h"
#include "ambdiag/core/error.h"
#include "rotor_krylov.h"

namespace ambdiag {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

Mode closed_form_mode(double f_hz, double zeta, const std::string& direction, const std::string& kind,
                      const std::string& label) {
  Mode m;
  m.f_hz = f_hz;
  m.zeta = zeta;
  const double w = kTwoPi * f_hz;
  m.eigenvalue = zeta < 1.0 ? std::complex<double>(-zeta * w, w * std::sqrt(1.0 - zeta * zeta))
                            : std::complex<double>(-zeta * w + w * std::sqrt(zeta * zeta - 1.0), 0.0);
  m.overdamped = zeta >= 1.0;
  m.direction = direction;
  m.kind = kind;
  m.label = label;
  return m;
}

// One rotor mode from an eigenvalue and (if shapes are kept) its vector q
// in the system's coordinates.
Mode rotor_mode(const PlantModel& plant, const RotorSystem& sys, std::complex<double> l, bool zero, bool real,
                const Eigen::VectorXcd* q) {
  Mode md;
  md.eigenvalue = l;
  md.f_hz = zero ? 0.0 : std::abs(l) / kTwoPi;
  md.zeta = md.f_hz == 0.0 ? 0.0 : -l.real() / std::abs(l);
  md.overdamped = real && md.f_hz > 0.0;
  md.direction = "radial";
  md.kind = "rotor";
  if (!q) return md;
  Eigen::VectorXcd full = sys.reduced() ? Eigen::VectorXcd(sys.basis.cast<std::complex<double>>() * *q) : *q;
  double fw = 0.0, bw = 0.0, peak = 0.0;
  for (int node = 0; node < plant.node_count(); ++node) {
    const std::complex<double> x = full(4 * node), y = full(4 * node + 1);
    const std::complex<double> j(0.0, 1.0);
    fw += std::norm(x + j * y);
    bw += std::norm(x - j * y);
    peak = std::max({peak, std::abs(x), std::abs(y)});
  }
  md.fwd_fraction = (fw + bw) > 0 ? fw / (fw + bw) : 0.0;
  if (!real && fw + bw > 0) md.whirl = md.fwd_fraction >= 0.5 ? Whirl::forward : Whirl::backward;
  // Normalise: largest displacement 1, phase of that entry 0.
  Eigen::Index at = 0;
  full.cwiseAbs().maxCoeff(&at);
  if (peak > 0) full /= full(at) / std::abs(full(at)) * peak;
  md.shape = std::move(full);
  return md;
}

// Keeps one mode per conjugate pair; a real eigenvalue is overdamped. Zero
// (rigid-body, free-free) eigenvalues are reported as f = 0, one mode per
// pair: round-off splits each double zero into a real or a complex pair.
// `vector(i)` gives the shape of eigenvalue i.
template <typename VectorOf>
void emit_rotor_modes(const PlantModel& plant, const RotorSystem& sys, const Eigen::VectorXcd& lam, double scale,
                      const ModalOptions& opt, VectorOf vector, std::vector<Mode>& out) {
  int zeros = 0;
  for (Eigen::Index i = 0; i < lam.size(); ++i) {
    const std::complex<double> l = lam(i);
    const double mag = std::abs(l);
    const bool real = std::abs(l.imag()) <= 1e-9 * scale;
    const bool zero = mag <= 1e-7 * scale;
    if (zero) {
      if (zeros++ % 2 == 1) continue;
    } else {
      if (!real && l.imag() < 0) continue;
      if (real && !opt.overdamped) continue;
    }
    if (opt.shapes) {
      const Eigen::VectorXcd q = vector(i);
      out.push_back(rotor_mode(plant, sys, l, zero, real, &q));
    } else {
      out.push_back(rotor_mode(plant, sys, l, zero, real, nullptr));
    }
  }
}

void add_dense_rotor_modes(const PlantModel& plant, const RotorSystem& sys, const ModalOptions& opt,
                           std::vector<Mode>& out) {
  const int n = sys.size();
  // Symmetrised, balanced first-order form. With M = L L^T, p = L^T q and
  // velocities scaled by a typical frequency s (both similarity transforms):
  //   A = [0  s I; -L^-1 K L^-T / s  -L^-1 C L^-T].
  // The plain [0 I; -M^-1 K  -M^-1 C] lost low eigenvalues of stiff models
  // (pinned ends at 1e14 N/m: first frequency 9 % off): its eigenvector
  // condition grows with w_max^2 and with the condition of M.
  const Eigen::LLT<Eigen::MatrixXd> llt{Eigen::MatrixXd(sys.m)};
  if (llt.info() != Eigen::Success) throw InputError("mass matrix is not positive definite (negative or missing mass?)");
  const auto lower = llt.matrixL();
  auto congruent = [&](const Eigen::MatrixXd& x) {  // L^-1 x L^-T
    const Eigen::MatrixXd y = lower.solve(x);
    return Eigen::MatrixXd(lower.solve(y.transpose()).transpose());
  };
  const Eigen::MatrixXd kt = congruent(Eigen::MatrixXd(sys.k));
  const double s = std::max(std::sqrt(kt.norm() / std::sqrt(static_cast<double>(n))), 1e-300);
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  a.topRightCorner(n, n).diagonal().setConstant(s);
  a.bottomLeftCorner(n, n) = -kt / s;
  a.bottomRightCorner(n, n) = -congruent(sys.dense_damping());
  Eigen::EigenSolver<Eigen::MatrixXd> es(a, opt.shapes);
  if (es.info() != Eigen::Success) throw InputError("rotor eigenproblem did not converge");
  const Eigen::VectorXcd lam = es.eigenvalues();
  const double scale = std::max(1.0, lam.cwiseAbs().maxCoeff());
  emit_rotor_modes(plant, sys, lam, scale, opt, [&](Eigen::Index i) {
    const Eigen::VectorXcd p = es.eigenvectors().col(i).head(n);
    Eigen::VectorXcd v(n);  // q = L^-T p
    v.real() = llt.matrixU().solve(Eigen::VectorXd(p.real()));
    v.imag() = llt.matrixU().solve(Eigen::VectorXd(p.imag()));
    return v;
  }, out);
}

void add_rotor_modes(const PlantModel& plant, double speed_rpm, const ModalOptions& opt, ModalResult& r) {
  StructuralDampingOptions damping = opt.damping;
  const bool band = std::isfinite(opt.f_max_hz);
  if (band) damping.omega_max_rad_per_s = kTwoPi * opt.f_max_hz;
  // States of the first-order form (checked before any work).
  const int states = plant.reduction.kind == Reduction::Kind::modal ? 4 * (2 + plant.reduction.n_elastic_modes)
                                                                    : 8 * plant.node_count();
  constexpr int kDenseMaxStates = 400, kDenseHardMaxStates = 1600;
  const bool krylov = opt.solver == ModalSolver::krylov ||
                      (opt.solver == ModalSolver::automatic && band && states > kDenseMaxStates);
  if (!krylov && opt.solver == ModalSolver::automatic && states > kDenseHardMaxStates) {
    throw InputError("modal analysis: " + std::to_string(states) +
                     " states are too many for the dense solver; give f_max to find the modes below it");
  }
  const RotorSystem sys = assemble_rotor(plant, speed_rpm, damping);
  r.damping_modes_per_plane = sys.damping_modes_per_plane;
  if (!krylov) {
    r.solver = "dense";
    add_dense_rotor_modes(plant, sys, opt, r.modes);
    return;
  }
  if (!band || !(opt.f_max_hz > 0)) throw InputError("modal analysis: the Krylov solver needs f_max > 0");
  const double omega_band = kTwoPi * opt.f_max_hz;
  const detail::BandModes bm = detail::rotor_modes_in_band(sys, omega_band, opt.shapes);
  r.solver = "krylov";
  r.krylov_size = bm.krylov_size;
  r.max_residual = bm.max_residual;
  r.converged = bm.converged;
  emit_rotor_modes(plant, sys, bm.eigenvalues, omega_band, opt, [&](Eigen::Index i) {
    return Eigen::VectorXcd(bm.shapes.col(i));
  }, r.modes);
}

// Fraction of a lateral mode's displacement (x and y along the shaft) that a
// straight line in z does not explain: near 0 for rigid-body modes.
double bending_fraction(const Eigen::VectorXcd& shape, const std::vector<double>& z) {
  const int nodes = static_cast<int>(z.size());
  Eigen::MatrixXcd a(nodes, 2);
  for (int i = 0; i < nodes; ++i) a.row(i) << 1.0, z[static_cast<size_t>(i)];
  double resid = 0.0, total = 0.0;
  for (int d = 0; d < 2; ++d) {
    Eigen::VectorXcd v(nodes);
    for (int i = 0; i < nodes; ++i) v(i) = shape(4 * i + d);
    const Eigen::VectorXcd fit = a * a.colPivHouseholderQr().solve(v);
    resid += (v - fit).squaredNorm();
    total += v.squaredNorm();
  }
  return total > 0 ? resid / total : 0.0;
}

// Labels rotor modes "radial rigid body k" / "radial bending k", counting
// forward and backward modes separately so that a whirl pair shares k.
void label_rotor_modes(std::vector<Mode>& modes, const std::vector<double>& z) {
  constexpr double kRigidBendingFraction = 0.1;
  int count[2][3] = {};  // [rigid?][whirl]
  for (auto& m : modes) {
    if (m.kind != "rotor" || m.shape.size() == 0 || m.overdamped || m.f_hz == 0.0) continue;
    const bool rigid = bending_fraction(m.shape, z) < kRigidBendingFraction;
    const int k = ++count[rigid ? 1 : 0][static_cast<int>(m.whirl)];
    m.label = std::string(rigid ? "radial rigid body " : "radial bending ") + std::to_string(k);
  }
}

}  // namespace

std::string to_string(Whirl w) {
  switch (w) {
    case Whirl::forward: return "forward";
    case Whirl::backward: return "backward";
    case Whirl::none: return "none";
  }
  return "none";
}

double Mode::log_decrement() const {
  if (zeta >= 1.0) return std::numeric_limits<double>::infinity();
  return kTwoPi * zeta / std::sqrt(1.0 - zeta * zeta);
}

ModalResult modal_analysis(const PlantModel& plant, double speed_rpm, const ModalOptions& opt) {
  if (!(speed_rpm >= 0.0) || !std::isfinite(speed_rpm)) throw InputError("speed_rpm: must be >= 0");
  ModalResult r;
  r.speed_rpm = speed_rpm;
  add_rotor_modes(plant, speed_rpm, opt, r);
  for (const auto& h : plant.housings) {
    r.modes.push_back(closed_form_mode(h.f_hz, h.zeta, "radial", "housing", h.name.empty() ? "housing " + h.plane : h.name));
  }
  if (plant.axial) {
    const auto& ax = *plant.axial;
    const double m = ax.m_kg.value_or(plant.rotor_mass_kg());
    if (ax.k_n_per_m > 0.0) {
      const double w = std::sqrt(ax.k_n_per_m / m);
      r.modes.push_back(closed_form_mode(w / kTwoPi, ax.c_ns_per_m / (2.0 * std::sqrt(ax.k_n_per_m * m)), "axial", "axial",
                                         "axial rigid body"));
    } else {
      r.modes.push_back(closed_form_mode(0.0, 0.0, "axial", "axial", "axial rigid body"));
    }
    for (const auto& h : ax.housings) {
      r.modes.push_back(closed_form_mode(h.f_hz, h.zeta, "axial", "axial_housing", h.name.empty() ? "axial housing" : h.name));
    }
  }
  std::stable_sort(r.modes.begin(), r.modes.end(), [](const Mode& a, const Mode& b) { return a.f_hz < b.f_hz; });
  label_rotor_modes(r.modes, plant.node_positions_m());
  return r;
}

}  // namespace ambdiag
