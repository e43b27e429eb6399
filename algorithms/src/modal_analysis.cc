#include "ambdiag/algorithms/modal_analysis.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "ambdiag/algorithms/rotor_system.h"
#include "ambdiag/core/error.h"

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

void add_rotor_modes(const PlantModel& plant, double speed_rpm, const ModalOptions& opt, std::vector<Mode>& out) {
  const RotorSystem sys = assemble_rotor(plant, speed_rpm);
  const int n = sys.size();
  const Eigen::MatrixXd a = first_order_matrix(sys);
  Eigen::EigenSolver<Eigen::MatrixXd> es(a, opt.shapes);
  if (es.info() != Eigen::Success) throw InputError("rotor eigenproblem did not converge");

  const Eigen::VectorXcd lam = es.eigenvalues();
  const double scale = std::max(1.0, lam.cwiseAbs().maxCoeff());
  const int nodes = plant.node_count();
  for (int i = 0; i < lam.size(); ++i) {
    const std::complex<double> l = lam(i);
    const double mag = std::abs(l);
    // One mode per conjugate pair; a real eigenvalue is overdamped. Zero
    // (rigid-body, free-free) eigenvalues are reported as f = 0.
    const bool real = std::abs(l.imag()) <= 1e-9 * scale;
    if (!real && l.imag() < 0) continue;
    if (real && !opt.overdamped) continue;
    Mode md;
    md.eigenvalue = l;
    md.f_hz = mag <= 1e-7 * scale ? 0.0 : mag / kTwoPi;
    md.zeta = md.f_hz == 0.0 ? 0.0 : -l.real() / mag;
    md.overdamped = real && md.f_hz > 0.0;
    md.direction = "radial";
    md.kind = "rotor";
    if (opt.shapes) {
      const Eigen::VectorXcd v = es.eigenvectors().col(i).head(n);
      Eigen::VectorXcd full = sys.reduced() ? Eigen::VectorXcd(sys.basis.cast<std::complex<double>>() * v) : v;
      double fw = 0.0, bw = 0.0, peak = 0.0;
      for (int node = 0; node < nodes; ++node) {
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
    }
    out.push_back(std::move(md));
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
  add_rotor_modes(plant, speed_rpm, opt, r.modes);
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
  return r;
}

}  // namespace ambdiag
