#include "ambdiag/algorithms/simulation/amb_loop.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <sstream>

#include "amb_discretise.h"
#include "ambdiag/algorithms/model/rotor_system.h"
#include "ambdiag/core/error.h"

namespace ambdiag {

namespace {

constexpr double kPi = std::numbers::pi;

// The continuous mechanics: states s, true bearing forces f (one per
// actuator) and the unbalance force (x, y) as inputs; outputs the air gaps
// and the sensor displacements, both relative to the housings.
struct Mechanics {
  Eigen::MatrixXd a, b_f, b_d, c_gap, c_sens;
};

bool same_axis(const MeasurementPoint& s, const MeasurementPoint& a) {
  return s.is_axial() ? a.is_axial() : (!a.is_axial() && s.plane == a.plane && s.dir == a.dir);
}

Mechanics build_mechanics(const PlantModel& p, double controller_rate_hz, int unbalance_node) {
  StructuralDampingOptions damping;
  damping.omega_max_rad_per_s = kPi * controller_rate_hz;
  const RotorSystem sys = assemble_rotor(p, p.speed_rpm, damping);
  const Eigen::Index n = sys.size();
  const Eigen::MatrixXd a_rot = first_order_matrix(sys);
  const Eigen::LDLT<Eigen::MatrixXd> mass{Eigen::MatrixXd(sys.m)};

  // Extra single-DOF systems: housings (pushed by -f of their plane and
  // direction) and the axial rotor with its housings.
  struct Sdof {
    double m, k, c;
    std::string plane;
    char dir;
    bool rotor;  // the axial rotor itself (pushed by +f)
  };
  std::vector<Sdof> extra;
  for (const auto& h : p.housings) {
    const double w0 = 2 * kPi * h.f_hz;
    for (const auto& d : h.dirs) extra.push_back({h.m_kg, h.m_kg * w0 * w0, 2 * h.zeta * w0 * h.m_kg, h.plane, d[0], false});
  }
  const bool axial_points = std::any_of(p.actuators.begin(), p.actuators.end(), [](auto& a) { return a.is_axial(); }) ||
                            std::any_of(p.sensors.begin(), p.sensors.end(), [](auto& s) { return s.is_axial(); });
  if (axial_points) {
    if (!p.axial) throw InputError("plant model: axial sensor or actuator without an axial model");
    const AxialModel& ax = *p.axial;
    extra.push_back({ax.m_kg.value_or(p.rotor_mass_kg()), ax.k_n_per_m, ax.c_ns_per_m, "Z", 'z', true});
    for (const auto& h : ax.housings) {
      const double w0 = 2 * kPi * h.f_hz;
      extra.push_back({h.m_kg, h.m_kg * w0 * w0, 2 * h.zeta * w0 * h.m_kg, "Z", 'z', false});
    }
  }
  const Eigen::Index ns = 2 * n + 2 * static_cast<Eigen::Index>(extra.size());
  const auto n_act = static_cast<Eigen::Index>(p.actuators.size());
  const auto n_sen = static_cast<Eigen::Index>(p.sensors.size());
  Mechanics m;
  m.a = Eigen::MatrixXd::Zero(ns, ns);
  m.a.topLeftCorner(2 * n, 2 * n) = a_rot;
  m.b_f = Eigen::MatrixXd::Zero(ns, n_act);
  m.b_d = Eigen::MatrixXd::Zero(ns, 2);
  m.c_gap = Eigen::MatrixXd::Zero(n_act, ns);
  m.c_sens = Eigen::MatrixXd::Zero(n_sen, ns);
  for (size_t e = 0; e < extra.size(); ++e) {
    const Eigen::Index i = 2 * n + 2 * static_cast<Eigen::Index>(e);
    m.a(i, i + 1) = 1.0;
    m.a(i + 1, i) = -extra[e].k / extra[e].m;
    m.a(i + 1, i + 1) = -extra[e].c / extra[e].m;
  }
  // Displacement of a point relative to its housing: rotor row minus the
  // housings of its plane and direction (axial: the axial rotor minus the
  // axial housings).
  auto relative_row = [&](const MeasurementPoint& pt) {
    Eigen::RowVectorXd row = Eigen::RowVectorXd::Zero(ns);
    if (!pt.is_axial()) row.head(n) = sys.dof_row(lateral_dof(*pt.node, pt.dir));
    for (size_t e = 0; e < extra.size(); ++e) {
      const bool match = pt.is_axial() ? extra[e].dir == 'z' : (extra[e].plane == pt.plane && extra[e].dir == pt.dir);
      if (match) row(2 * n + 2 * static_cast<Eigen::Index>(e)) = extra[e].rotor ? 1.0 : -1.0;
    }
    return row;
  };
  for (Eigen::Index j = 0; j < n_act; ++j) {
    const auto& act = p.actuators[static_cast<size_t>(j)];
    m.c_gap.row(j) = relative_row(act);
    // Force on the rotor (+) and on its housings (-): the transpose of the
    // relative displacement row, divided by the masses.
    if (!act.is_axial()) m.b_f.col(j).segment(n, n) = mass.solve(sys.dof_row(lateral_dof(*act.node, act.dir)).transpose());
    for (size_t e = 0; e < extra.size(); ++e) {
      const Eigen::Index i = 2 * n + 2 * static_cast<Eigen::Index>(e);
      const double sign = m.c_gap(j, i);
      if (sign != 0.0) m.b_f(i + 1, j) = sign / extra[e].m;
    }
  }
  for (Eigen::Index i = 0; i < n_sen; ++i) m.c_sens.row(i) = relative_row(p.sensors[static_cast<size_t>(i)]);
  if (unbalance_node >= 0) {
    if (unbalance_node >= p.node_count()) throw InputError("unbalance node " + std::to_string(unbalance_node) + " is not a node of the rotor");
    m.b_d.col(0).segment(n, n) = mass.solve(sys.dof_row(lateral_dof(unbalance_node, 'x')).transpose());
    m.b_d.col(1).segment(n, n) = mass.solve(sys.dof_row(lateral_dof(unbalance_node, 'y')).transpose());
  }
  return m;
}

// 4th-order Butterworth as two second-order sections, states (w, w' / wc)
// per section: y'' + (wc/Q) y' + wc^2 y = wc^2 u.
constexpr double kButterQ[2] = {0.5411961001461971, 1.3065629648763766};

}  // namespace

struct AmbLoop::Impl {
  AmbLoopReport report;
  double h = 0;          // controller period
  int decimation = 1;
  double omega_spin = 0;
  double unbalance_kg_m = 0;
  double sigma_x = 0, sigma_i = 0;
  Eigen::Index n_act = 0, n_sen = 0;
  detail::ZohModel zoh;        // states [mechanics; filters], inputs [i; unbalance]
  Eigen::MatrixXd c_ctrl;      // sensor reading seen by each actuator's controller (balanced)
  Eigen::MatrixXd c_rec;       // filtered force and displacement channels (balanced)
  Eigen::VectorXd x;           // state (balanced)
  Eigen::VectorXd e_prev, d_prev, integ, u_prev;
  Eigen::VectorXd kp, kd, ki, k_i;
  double d_a = 0, d_b = 0;     // derivative filter: d_k = d_a d_{k-1} + d_b kd (e_k - e_{k-1})
  int64_t step = 0;
  std::mt19937_64 rng;
};

AmbLoop::~AmbLoop() = default;
AmbLoop::AmbLoop(AmbLoop&&) noexcept = default;
AmbLoop& AmbLoop::operator=(AmbLoop&&) noexcept = default;
const AmbLoopReport& AmbLoop::report() const { return impl_->report; }
double AmbLoop::record_rate_hz() const { return 1.0 / (impl_->h * impl_->decimation); }
double AmbLoop::controller_rate_hz() const { return 1.0 / impl_->h; }
double AmbLoop::time_s() const { return static_cast<double>(impl_->step) * impl_->h; }

AmbLoop::AmbLoop(const PlantModel& plant_in, const AmbLoopOptions& o) : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  if (!(o.controller_rate_hz > 0) || !std::isfinite(o.controller_rate_hz)) throw InputError("controller rate must be > 0");
  if (o.decimation < 1) throw InputError("decimation must be >= 1");
  if (plant_in.actuators.empty() || plant_in.sensors.empty()) throw InputError("plant model: the AMB loop needs sensors and actuators");
  s.h = 1.0 / o.controller_rate_hz;
  s.decimation = o.decimation;
  s.n_act = static_cast<Eigen::Index>(plant_in.actuators.size());
  s.n_sen = static_cast<Eigen::Index>(plant_in.sensors.size());
  if (!o.sensor_gain.empty() && static_cast<Eigen::Index>(o.sensor_gain.size()) != s.n_sen)
    throw InputError("sensor_gain: one per sensor (" + std::to_string(s.n_sen) + ")");
  if (!o.actuator_gain.empty() && static_cast<Eigen::Index>(o.actuator_gain.size()) != s.n_act)
    throw InputError("actuator_gain: one per actuator (" + std::to_string(s.n_act) + ")");
  s.sigma_x = o.displacement_noise_m;
  s.sigma_i = o.current_noise_a;
  s.rng.seed(o.seed);
  s.omega_spin = plant_in.speed_rpm * 2 * kPi / 60.0;
  s.unbalance_kg_m = o.unbalance_kg_m;

  // Links of kind "bearing" on an actuator node stand for the closed AMB
  // loop: they leave the mechanics and set the controller's targets.
  PlantModel plant = plant_in;
  std::vector<std::optional<LinkCoefficients>> bearing_link(static_cast<size_t>(s.n_act));
  std::erase_if(plant.links, [&](const Link& l) {
    if (l.kind != "bearing") return false;
    bool used = false;
    for (size_t j = 0; j < plant.actuators.size(); ++j)
      if (!plant.actuators[j].is_axial() && plant.actuators[j].node == l.node) {
        bearing_link[j] = l.at_speed(plant.speed_rpm);
        used = true;
      }
    return used;
  });

  const Mechanics mech = build_mechanics(plant, o.controller_rate_hz, o.unbalance_kg_m != 0.0 ? o.unbalance_node : -1);
  const AmbLinearisation rad = linearise_amb(o.radial), ax = linearise_amb(o.axial);

  // Per actuator: law, gain, controller sensor, targets.
  AmbLoopReport& rep = s.report;
  s.k_i.resize(s.n_act);
  Eigen::VectorXd k_s(s.n_act), gain(s.n_act);
  std::vector<Eigen::Index> ctrl_sensor(static_cast<size_t>(s.n_act));
  const double rotor_share_kg = plant.rotor_mass_kg() / 2.0;
  for (Eigen::Index j = 0; j < s.n_act; ++j) {
    const auto& act = plant.actuators[static_cast<size_t>(j)];
    const AmbLinearisation& l = act.is_axial() ? ax : rad;
    s.k_i(j) = l.k_i_n_per_a;
    k_s(j) = l.k_s_n_per_m;
    gain(j) = o.actuator_gain.empty() ? 1.0 : o.actuator_gain[static_cast<size_t>(j)];
    Eigen::Index found = -1;
    for (Eigen::Index i = 0; i < s.n_sen && found < 0; ++i)
      if (same_axis(plant.sensors[static_cast<size_t>(i)], act)) found = i;
    if (found < 0) throw InputError("actuator " + act.name + ": no sensor of plane " + act.plane + ", direction " + act.dir + " for its controller");
    ctrl_sensor[static_cast<size_t>(j)] = found;
    double k_t = act.is_axial() ? o.axial_stiffness_n_per_m : o.radial_stiffness_n_per_m;
    double d_t = act.is_axial() ? o.axial_damping_ns_per_m : o.radial_damping_ns_per_m;
    if (const auto& bl = bearing_link[static_cast<size_t>(j)]) {
      const bool x = act.dir == 'x';
      k_t = (*bl)[static_cast<int>(x ? LinkCoef::kxx : LinkCoef::kyy)];
      d_t = (*bl)[static_cast<int>(x ? LinkCoef::cxx : LinkCoef::cyy)];
    }
    if (k_t == 0.0) k_t = l.k_s_n_per_m;
    const double m_share = act.is_axial() ? plant.axial->m_kg.value_or(plant.rotor_mass_kg()) : rotor_share_kg;
    if (d_t <= 0.0) d_t = 2.0 * 0.3 * std::sqrt(std::abs(k_t) * m_share);
    if (!std::isfinite(k_t) || !std::isfinite(d_t)) throw InputError("actuator " + act.name + ": bearing stiffness and damping targets must be finite");
    rep.k_i_n_per_a.push_back(l.k_i_n_per_a);
    rep.k_s_n_per_m.push_back(l.k_s_n_per_m);
    rep.stiffness_n_per_m.push_back(k_t);
    rep.damping_ns_per_m.push_back(d_t);
  }
  s.kp.resize(s.n_act);
  s.kd.resize(s.n_act);
  s.ki.resize(s.n_act);
  for (Eigen::Index j = 0; j < s.n_act; ++j) {
    const auto u = static_cast<size_t>(j);
    s.kp(j) = (rep.stiffness_n_per_m[u] + k_s(j)) / s.k_i(j);
    s.kd(j) = rep.damping_ns_per_m[u] / s.k_i(j);
    s.ki(j) = s.kp(j) * 2 * kPi * o.integral_corner_hz;
    rep.kp_a_per_m.push_back(s.kp(j));
    rep.kd_a_s_per_m.push_back(s.kd(j));
    rep.ki_a_per_m_s.push_back(s.ki(j));
  }
  const double f_d = o.derivative_corner_hz > 0 ? o.derivative_corner_hz : o.controller_rate_hz / 8.0;
  const double tau = 1.0 / (2 * kPi * f_d);
  s.d_a = (2 * tau - s.h) / (2 * tau + s.h);
  s.d_b = 2.0 / (2 * tau + s.h);

  // Continuous system: true force f = g (k_i i + k_s s), measured (i-s
  // method, nominal) f_m = k_i i + k_s s, sensor reading y = g_s x.
  const Eigen::Index nm = mech.a.rows();
  Eigen::VectorXd sg = Eigen::VectorXd::Ones(s.n_sen);
  for (Eigen::Index i = 0; i < s.n_sen && !o.sensor_gain.empty(); ++i) sg(i) = o.sensor_gain[static_cast<size_t>(i)];
  const Eigen::MatrixXd a_mech = mech.a + mech.b_f * (gain.cwiseProduct(k_s)).asDiagonal() * mech.c_gap;
  const Eigen::MatrixXd b_i = mech.b_f * (gain.cwiseProduct(s.k_i)).asDiagonal();
  const Eigen::MatrixXd f_meas_state = k_s.asDiagonal() * mech.c_gap;  // + k_i i
  const Eigen::MatrixXd y_state = sg.asDiagonal() * mech.c_sens;

  const double fs_rec = o.controller_rate_hz / o.decimation;
  const double fc = o.anti_alias_hz > 0 ? o.anti_alias_hz : 0.45 * fs_rec;
  const double wc = 2 * kPi * fc;
  const Eigen::Index n_ch = s.n_act + s.n_sen, nf = 4 * n_ch, n = nm + nf, n_u = s.n_act + 2;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n), b = Eigen::MatrixXd::Zero(n, n_u);
  a.topLeftCorner(nm, nm) = a_mech;
  b.topLeftCorner(nm, s.n_act) = b_i;
  b.block(0, s.n_act, nm, 2) = mech.b_d;
  s.c_rec = Eigen::MatrixXd::Zero(n_ch, n);
  for (Eigen::Index c = 0; c < n_ch; ++c) {
    const Eigen::Index f0 = nm + 4 * c;
    for (int sec = 0; sec < 2; ++sec) {
      const Eigen::Index w = f0 + 2 * sec;
      // w' = wc v; v' = wc (u - w) - (wc / Q) v
      a(w, w + 1) = wc;
      a(w + 1, w) = -wc;
      a(w + 1, w + 1) = -wc / kButterQ[sec];
      if (sec == 1) {
        a(w + 1, f0) = wc;
      } else if (c < s.n_act) {
        a.row(w + 1).head(nm) += wc * f_meas_state.row(c);
        b(w + 1, c) = wc * s.k_i(c);
      } else {
        a.row(w + 1).head(nm) += wc * y_state.row(c - s.n_act);
      }
    }
    s.c_rec(c, f0 + 2) = 1.0;
  }
  s.zoh = detail::zoh_discretise(a, b, s.h);
  rep.states = static_cast<int>(n);
  s.c_rec = s.c_rec * s.zoh.scale.asDiagonal();
  s.c_ctrl = Eigen::MatrixXd::Zero(s.n_act, n);
  for (Eigen::Index j = 0; j < s.n_act; ++j) s.c_ctrl.row(j).head(nm) = y_state.row(ctrl_sensor[static_cast<size_t>(j)]);
  s.c_ctrl = s.c_ctrl * s.zoh.scale.asDiagonal();

  // Closed loop over one controller step: state [x; e_prev; d_prev; integ; u_prev].
  const Eigen::Index na = s.n_act, nc = n + 4 * na;
  Eigen::MatrixXd cl = Eigen::MatrixXd::Zero(nc, nc);
  const Eigen::MatrixXd g_i = s.zoh.gamma.leftCols(na);
  // Rows of e_k, d_k, integ_k, u_k in terms of the current state.
  Eigen::MatrixXd e_row = Eigen::MatrixXd::Zero(na, nc), d_row = e_row, i_row = e_row, u_row = e_row;
  e_row.leftCols(n) = -s.c_ctrl;
  for (Eigen::Index j = 0; j < na; ++j) {
    d_row.row(j) = s.d_b * s.kd(j) * e_row.row(j);
    d_row(j, n + j) -= s.d_b * s.kd(j);
    d_row(j, n + na + j) += s.d_a;
    i_row.row(j) = s.ki(j) * s.h * e_row.row(j);
    // Without integral action the integrator stays 0: no eigenvalue 1 for it.
    if (s.ki(j) != 0.0) i_row(j, n + 2 * na + j) += 1.0;
    u_row.row(j) = s.kp(j) * e_row.row(j) + d_row.row(j) + i_row.row(j);
  }
  cl.topLeftCorner(n, n) = s.zoh.phi;
  cl.block(0, n + 3 * na, n, na) = g_i;
  cl.middleRows(n, na) = e_row;
  cl.middleRows(n + na, na) = d_row;
  cl.middleRows(n + 2 * na, na) = i_row;
  cl.middleRows(n + 3 * na, na) = u_row;
  rep.spectral_radius = detail::spectral_radius(cl);
  if (!(rep.spectral_radius < 1.0)) {
    std::ostringstream m;
    m.precision(9);
    m << "the AMB controller does not stabilise this plant (spectral radius " << rep.spectral_radius
      << " of the discrete closed loop); set the bearing stiffness and damping targets";
    throw InputError(m.str());
  }
  s.x = Eigen::VectorXd::Zero(n);
  s.e_prev = Eigen::VectorXd::Zero(na);
  s.d_prev = s.e_prev;
  s.integ = s.e_prev;
  s.u_prev = s.e_prev;
}

void AmbLoop::run(int64_t n_rec, const Reference& ref, Eigen::MatrixXd& r_n, Eigen::MatrixXd& f_n,
                  Eigen::MatrixXd& x_m) {
  Impl& s = *impl_;
  const Eigen::Index na = s.n_act;
  r_n.resize(na, n_rec);
  f_n.resize(na, n_rec);
  x_m.resize(s.n_sen, n_rec);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::vector<double> r(static_cast<size_t>(na));
  Eigen::VectorXd u(na + 2), e(na), rec(na + s.n_sen), next(s.x.size());
  int64_t k_ref = 0;
  for (int64_t k = 0; k < n_rec; ++k) {
    for (int sub = 0; sub < s.decimation; ++sub, ++s.step, ++k_ref) {
      const double t = static_cast<double>(s.step) * s.h;
      ref(k_ref, r);
      if (sub == 0) {
        rec.noalias() = s.c_rec * s.x;
        for (Eigen::Index j = 0; j < na; ++j) {
          r_n(j, k) = r[static_cast<size_t>(j)];
          f_n(j, k) = rec(j) + s.k_i(j) * s.sigma_i * gauss(s.rng);
        }
        for (Eigen::Index i = 0; i < s.n_sen; ++i) x_m(i, k) = rec(na + i) + s.sigma_x * gauss(s.rng);
      }
      // Controller: measurement now, output one step later.
      e.noalias() = -(s.c_ctrl * s.x);
      for (Eigen::Index j = 0; j < na; ++j) {
        e(j) -= s.sigma_x * gauss(s.rng);
        u(j) = s.u_prev(j) + r[static_cast<size_t>(j)] / s.k_i(j);
        const double d = s.d_a * s.d_prev(j) + s.d_b * s.kd(j) * (e(j) - s.e_prev(j));
        s.integ(j) += s.ki(j) * s.h * e(j);
        s.u_prev(j) = s.kp(j) * e(j) + d + s.integ(j);
        s.d_prev(j) = d;
        s.e_prev(j) = e(j);
      }
      const double fu = s.unbalance_kg_m * s.omega_spin * s.omega_spin;
      u(na) = fu * std::cos(s.omega_spin * t);
      u(na + 1) = fu * std::sin(s.omega_spin * t);
      next.noalias() = s.zoh.phi * s.x;
      next.noalias() += s.zoh.gamma * u;
      s.x.swap(next);
    }
  }
}

}  // namespace ambdiag
