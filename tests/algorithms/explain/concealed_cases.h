// Concealed cases for explain (issue 18): on two machines, the shared
// reference pump (reference_pump/plant.json, read at run time, never
// copied) and the second pump of tests/support/second_pump.h, one effect
// concealed from the nominal model per case, each at the machine's speed,
// recorded on 1..1000 Hz (1 Hz lines) with complex Gaussian noise of 1 % of
// each entry's RMS and sigma columns (explain_support.h), fixed seeds:
//
//   effect              nominal model                   truth (what made the recording)
//   gyroscopic_omitted  every disk's Ip = 0             the machine (Ip as designed)
//   added_mass          the machine                     + a disk {m, Id, Ip = 0} at a disk node
//   seal_cross_coupling the machine                     + kxy = -kyx = k, cxy = -cyx = c at one seal
//   coupling_omitted    the machine without its         the machine (coupling at the drive end,
//                       drive-end coupling link         node 0)
//   absorber            the machine                     + a mass m on a spring k and damper c
//                                                       attached to a mid-rotor node in x and y,
//                                                       which the plant format cannot express
//
// The absorber's FRF is exact: with the rotor receptance G = Z^-1 of the
// lateral system (rotor_receptance.h) and U the node's x and y translation
// DOFs, the absorber adds the dynamic stiffness
//
//   z(w) = -w^2 m (k + j w c) / (k + j w c - w^2 m)   on each of x and y,
//
// so by Woodbury  G'[s, a] = G[s, a] - G[s, U] (I + z G[U, U])^-1 z G[U, a].
// The recording is the machine's synthesized FRF plus G'[s, a] - G[s, a]
// on the lateral entries (housings, the axial model and the lateral-axial
// zeros are unchanged). concealed_cases_test.cc checks the receptance against
// the synthesis (m = 0) and the rigid limit (k -> inf) against the synthesis
// with a point mass at the node.
#pragma once

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdarg>
#include <cstdio>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/LU>
#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/explain/explain.h"
#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/algorithms/model/rotor_receptance.h"
#include "ambdiag/algorithms/model/rotor_system.h"
#include "ambdiag/core/plant_model.h"
#include "explain_support.h"
#include "second_pump.h"
#include "test_support.h"

namespace ambdiag::testing {

// A tuned mass (vibration absorber) on one rotor node, x and y alike.
struct Absorber {
  int node = 0;
  double m_kg = 0.0, k_n_per_m = 0.0, c_ns_per_m = 0.0;
  double f_hz() const { return std::sqrt(k_n_per_m / m_kg) / (2 * M_PI); }
  double zeta() const { return c_ns_per_m / (2 * std::sqrt(k_n_per_m * m_kg)); }
  static Absorber tuned(int node, double m_kg, double f_hz, double zeta) {
    const double k = m_kg * std::pow(2 * M_PI * f_hz, 2);
    return {node, m_kg, k, 2 * zeta * std::sqrt(k * m_kg)};
  }
  // Dynamic stiffness it adds to the node's x (and y) translation, N/m.
  std::complex<double> z(double w) const {
    const std::complex<double> kc(k_n_per_m, w * c_ns_per_m);
    return -w * w * m_kg * kc / (kc - w * w * m_kg);
  }
};

// The concealed physics as explain should name it. `parameters` holds the
// truth in explain's parameter names where explain reports the value
// (added_mass: kg, Id; seal_cross_coupling: k, c) and the plant values that
// the improved model must carry otherwise (gyroscopic: Ip per disk and
// Ip_total; coupling_stiffness: k, c of the link at `location.node`).
struct TruthPhysics {
  std::string physics;
  nlohmann::json location, parameters;
};

struct ConcealedCase {
  std::string name;     // "reference_pump/added_mass"
  std::string machine;  // "reference_pump" or "second_pump"
  std::string effect;   // gyroscopic_omitted, added_mass, seal_cross_coupling, coupling_omitted, absorber
  PlantModel nominal;   // given to explain
  PlantModel truth;     // the plant that made the recording (absorber: without the absorber)
  FrfData measured;
  std::optional<TruthPhysics> physics;  // empty: outside the catalogue ("unexplained")
  std::optional<Absorber> absorber;
  double extra_mode_hz = 0.0;  // absorber: its own mode in the recording (largest change beyond a rigid mass near its tuning)
  double absorber_excess = 0.0;     // absorber: 9-line mean |r|^2 near its mode against the best plain mass (record())
  double best_plain_mass_kg = 0.0;  // absorber: that mass
  std::string note;                 // the case in words
  // Variants (concealed_case_variant): the seed, the drawn truth in short,
  // how many draws were discarded before this one, and the nominal model's
  // chi2 per value on the recording (1 for a right model).
  unsigned seed = 0;
  std::string drawn;
  int discarded = 0;
  double chi2_per_value_before = 0.0;
};

inline const std::vector<std::string>& concealed_machines() {
  static const std::vector<std::string> m = {"reference_pump", "second_pump"};
  return m;
}
inline const std::vector<std::string>& concealed_effects() {
  static const std::vector<std::string> e = {"gyroscopic_omitted", "added_mass", "seal_cross_coupling", "coupling_omitted",
                                             "absorber"};
  return e;
}

// The shared reference pump, read at run time.
inline PlantModel reference_pump_model() { return read_plant_file(data_file("reference_pump/plant.json").string()); }

// The machines of the variations (concealed_case_variant): the two above
// and a third pump.
inline const std::vector<std::string>& concealed_variant_machines() {
  static const std::vector<std::string> m = {"reference_pump", "second_pump", "third_pump"};
  return m;
}

// A third machine for the variations, made from the reference pump's model
// like second_pump.h (same materials, 21 elements, sensor and actuator
// layout): a two-stage pump on a shorter (x 0.9), slimmer (x 0.94) shaft at
// 2400 rpm (a variable-speed drive), impellers at nodes 10 and 13, three
// fluid seals (impeller seal at 9, interstage seal at 12, both kind `seal`;
// balance piston at 14) with speed tables by the law of second_pump.h, a
// softer coupling, a housing resonance on plane B only.
inline PlantModel third_pump(const PlantModel& reference) {
  constexpr double rpm0 = 2400.0;
  PlantModel p = reference;
  p.name = "third pump: two stages, shorter and slimmer shaft, 2400 rpm (test fleet)";
  p.speed_rpm = rpm0;
  for (auto& e : p.shaft) {
    e.length_m *= 0.9;
    e.od_m *= 0.94;
    e.id_m *= 0.94;
  }
  p.disks.clear();
  p.disks.push_back({"amb_A_laminations", 3, 5.0, 0.0075, 0.0083});
  p.disks.push_back({"thrust_disk", 6, 1.8, 0.0030, 0.0058});
  p.disks.push_back({"impeller_1", 10, 1.7, 0.0022, 0.0037});
  p.disks.push_back({"impeller_2", 13, 1.7, 0.0022, 0.0037});
  p.disks.push_back({"amb_B_laminations", 19, 5.0, 0.0075, 0.0083});
  auto fluid = [rpm0](const std::string& name, const std::string& kind, int node, double k, double kc, double c, double cc, double m) {
    return detail::fluid_link(name, kind, node, k, kc, c, cc, m, rpm0, {0.0, 1000.0, 2000.0, rpm0, 3000.0});
  };
  p.links.clear();
  p.links.push_back(fluid("impeller_seal", "seal", 9, 1.9e5, 2.0e4, 420.0, 60.0, 0.6));
  p.links.push_back(fluid("interstage_seal", "seal", 12, 2.4e5, 3.0e4, 520.0, 80.0, 0.7));
  p.links.push_back(fluid("balance_piston", "balance_piston", 14, 3.0e5, 5.2e4, 3000.0, 95.0, 2.6));
  p.links.push_back(detail::plain_link("mechanical_seal_1", "mechanical_seal", 8, 9.0e4, 1400.0));
  p.links.push_back(detail::plain_link("mechanical_seal_2", "mechanical_seal", 15, 9.0e4, 1400.0));
  p.links.push_back(detail::plain_link("coupling", "coupling", 0, 6.5e5, 25.0));
  p.housings.clear();
  p.housings.push_back({"housing_B", "B", {"x", "y"}, 410.0, 0.05, 70.0});
  if (p.axial) {
    p.axial->m_kg.reset();
    p.axial->k_n_per_m = 1.1e6;
    p.axial->c_ns_per_m = 2400.0;
  }
  validate_plant(p);
  return p;
}

inline PlantModel concealed_machine(const PlantModel& reference, const std::string& machine) {
  if (machine == "reference_pump") return reference;
  if (machine == "second_pump") return second_pump(reference);
  if (machine == "third_pump") return third_pump(reference);
  throw std::invalid_argument("concealed_machine: unknown machine " + machine);
}

namespace concealed_detail {

inline size_t link_named(const PlantModel& p, const std::string& name) {
  for (size_t i = 0; i < p.links.size(); ++i)
    if (p.links[i].name == name) return i;
  throw std::invalid_argument("no link " + name + " in " + p.name);
}

// printf into a string (the drawn truth in short).
__attribute__((format(printf, 1, 2))) inline std::string fmt(const char* f, ...) {
  char buf[256];
  va_list ap;
  va_start(ap, f);
  std::vsnprintf(buf, sizeof buf, f, ap);
  va_end(ap);
  return buf;
}

// kxy = -kyx += k, cxy = -cyx += c at top level and in the speed-table rows that state them.
inline void add_cross_coupling(Link& l, double k, double c) {
  auto add = [&](LinkCoef coef, double d) {
    l.coef[static_cast<size_t>(coef)] += d;
    for (auto& row : l.table)
      if (row.values[static_cast<size_t>(coef)]) *row.values[static_cast<size_t>(coef)] += d;
  };
  add(LinkCoef::kxy, k);
  add(LinkCoef::kyx, -k);
  add(LinkCoef::cxy, c);
  add(LinkCoef::cyx, -c);
}

}  // namespace concealed_detail

// Lateral receptance of `plant` at `speed_rpm` between each entry's sensor
// and actuator DOFs, before (g) and after (g_abs) attaching the absorber,
// per entry (outer) and line (inner); zero for entries that are not lateral.
struct AbsorberReceptance {
  std::vector<std::vector<std::complex<double>>> g, g_abs;
};

// The receptance blocks of one rotor for absorbers at one node: one
// eigen-decomposition, then any number of absorbers (or rigid masses,
// k -> inf) at that node by Woodbury at a few 2 x 2 solves per line.
class AbsorberModel {
 public:
  AbsorberModel(const PlantModel& plant, double speed_rpm, const FrfData& like, int node) : node_(node), entries_(like.entries.size()) {
    for (double f : like.freq_hz) omega_.push_back(2 * M_PI * f);
    StructuralDampingOptions damping;  // as synthesize_frf: omega_max from the highest line
    damping.omega_max_rad_per_s = omega_.back();
    const RotorSystem sys = assemble_rotor(plant, speed_rpm, damping);
    const ambdiag::detail::RotorReceptance g(sys, omega_);
    std::vector<int> rows, cols;
    auto index_of = [](std::vector<int>& v, int dof) {
      const auto it = std::find(v.begin(), v.end(), dof);
      if (it != v.end()) return static_cast<int>(it - v.begin());
      v.push_back(dof);
      return static_cast<int>(v.size()) - 1;
    };
    for (const auto& e : like.entries) {
      const MeasurementPoint* s = plant.find_sensor(e.output);
      const MeasurementPoint* u = plant.find_actuator(e.input);
      const bool lateral = s && u && !s->is_axial() && !u->is_axial() && s->node && u->node;
      row_of_.push_back(lateral ? index_of(rows, lateral_dof(*s->node, s->dir)) : -1);
      col_of_.push_back(lateral ? index_of(cols, lateral_dof(*u->node, u->dir)) : -1);
    }
    const std::vector<int> dofs = {lateral_dof(node, 'x'), lateral_dof(node, 'y')};
    const Eigen::MatrixXcd g_sa = g.block(rows, cols), g_su = g.block(rows, dofs), g_uu = g.block(dofs, dofs),
                           g_ua = g.block(dofs, cols);
    const auto nr = static_cast<Eigen::Index>(rows.size()), nc = static_cast<Eigen::Index>(cols.size());
    for (size_t l = 0; l < omega_.size(); ++l) {
      const auto li = static_cast<Eigen::Index>(l);
      Eigen::MatrixXcd sa(nr, nc), su(nr, 2), uu(2, 2), ua(2, nc);
      for (Eigen::Index r = 0; r < nr; ++r) {
        for (Eigen::Index c = 0; c < nc; ++c) sa(r, c) = g_sa(li, r * nc + c);
        for (Eigen::Index c = 0; c < 2; ++c) su(r, c) = g_su(li, r * 2 + c);
      }
      for (Eigen::Index r = 0; r < 2; ++r) {
        for (Eigen::Index c = 0; c < 2; ++c) uu(r, c) = g_uu(li, r * 2 + c);
        for (Eigen::Index c = 0; c < nc; ++c) ua(r, c) = g_ua(li, r * nc + c);
      }
      sa_.push_back(sa), su_.push_back(su), uu_.push_back(uu), ua_.push_back(ua);
    }
  }

  AbsorberReceptance apply(const Absorber& a) const {
    using cd = std::complex<double>;
    if (a.node != node_) throw std::invalid_argument("AbsorberModel: absorber at another node");
    AbsorberReceptance out;
    out.g.assign(entries_, std::vector<cd>(omega_.size(), cd(0.0, 0.0)));
    out.g_abs = out.g;
    for (size_t l = 0; l < omega_.size(); ++l) {
      const cd z = a.z(omega_[l]);
      const Eigen::Matrix2cd lhs = Eigen::Matrix2cd::Identity() + z * uu_[l];
      const Eigen::MatrixXcd changed = sa_[l] - su_[l] * lhs.partialPivLu().solve(z * ua_[l]);
      for (size_t e = 0; e < entries_; ++e) {
        if (row_of_[e] < 0) continue;
        out.g[e][l] = sa_[l](row_of_[e], col_of_[e]);
        out.g_abs[e][l] = changed(row_of_[e], col_of_[e]);
      }
    }
    return out;
  }

 private:
  int node_;
  size_t entries_;
  std::vector<double> omega_;
  std::vector<int> row_of_, col_of_;
  std::vector<Eigen::MatrixXcd> sa_, su_, uu_, ua_;
};

inline AbsorberReceptance absorber_receptance(const PlantModel& plant, double speed_rpm, const FrfData& like,
                                              const Absorber& a) {
  return AbsorberModel(plant, speed_rpm, like, a.node).apply(a);
}

namespace concealed_detail {

// The recording of a case whose truth and absorber are set: the truth's
// synthesis, the absorber's change on the lateral entries, noise (seed).
// For an absorber also its own mode (extra_mode_hz: against the same mass
// fixed to the node, the line of the largest change within 6 % of its
// tuning) and how far it stands out of the best plain mass
// (absorber_excess: over the entries and the 9-line windows within 3 % of
// its mode, the largest mean |r|^2 of the recording against the truth plus
// the rigid point mass at the node whose kg, on a grid of 0..1.5 x the
// absorber's mass in steps of 0.02, fits the whole recording best).
inline void record(ConcealedCase& c, unsigned noise_seed) {
  const std::vector<double> grid = frequency_grid(1.0, 1000.0, 1.0);
  c.measured = synthesize_frf(c.truth, c.truth.speed_rpm, grid, {FrfMethod::modal});
  c.measured.speed_rpm = c.truth.speed_rpm;
  if (!c.absorber) {
    add_recording_noise(c.measured, 0.0, noise_seed);
    return;
  }
  const AbsorberModel am(c.truth, c.truth.speed_rpm, c.measured, c.absorber->node);
  const AbsorberReceptance ar = am.apply(*c.absorber);
  const auto rigid_mass = [&](double kg) { return am.apply(Absorber{c.absorber->node, kg, 1e13, 0.0}); };
  const AbsorberReceptance rigid = rigid_mass(c.absorber->m_kg);
  const FrfData plain = c.measured;  // the truth without the absorber
  std::vector<double> change(grid.size(), 0.0);
  for (size_t e = 0; e < c.measured.entries.size(); ++e) {
    auto& h = c.measured.entries[e].h;
    double s = 0.0;
    for (const auto& v : h) s += std::norm(v);
    const double rms = std::sqrt(s / static_cast<double>(h.size()));
    for (size_t l = 0; l < grid.size(); ++l) {
      h[l] += ar.g_abs[e][l] - ar.g[e][l];
      if (rms > 0) change[l] += std::norm(ar.g_abs[e][l] - rigid.g_abs[e][l]) / (rms * rms);
    }
  }
  double best = -1.0;
  for (size_t l = 0; l < grid.size(); ++l)
    if (std::abs(grid[l] - c.absorber->f_hz()) <= 0.06 * c.absorber->f_hz() && change[l] > best) {
      best = change[l];
      c.extra_mode_hz = grid[l];
    }
  add_recording_noise(c.measured, 0.0, noise_seed);
  // The best plain mass and the absorber's excess over it.
  const auto residual = [&](const AbsorberReceptance& m, size_t e, size_t l) {
    return (plain.entries[e].h[l] + m.g_abs[e][l] - m.g[e][l] - c.measured.entries[e].h[l]) / c.measured.entries[e].sigma[l];
  };
  double best_chi2 = INFINITY;
  AbsorberReceptance best_mass;
  for (int i = 0; i <= 75; ++i) {
    const double kg = 0.02 * i * c.absorber->m_kg;
    AbsorberReceptance m = rigid_mass(kg);
    double chi2 = 0.0;
    for (size_t e = 0; e < c.measured.entries.size(); ++e)
      for (size_t l = 0; l < grid.size(); ++l) chi2 += std::norm(residual(m, e, l));
    if (chi2 < best_chi2) best_chi2 = chi2, best_mass = std::move(m), c.best_plain_mass_kg = kg;
  }
  c.absorber_excess = 0.0;
  const size_t n = grid.size();
  for (size_t e = 0; e < c.measured.entries.size(); ++e)
    for (size_t l = 4; l + 4 < n; ++l) {
      if (std::abs(grid[l] - c.extra_mode_hz) > 0.03 * c.extra_mode_hz) continue;
      double s = 0.0;
      for (size_t j = l - 4; j <= l + 4; ++j) s += std::norm(residual(best_mass, e, j));
      c.absorber_excess = std::max(c.absorber_excess, s / 9.0);
    }
}

// The truth's coupling link i left out of the nominal model: the expected
// answer is a coupling stiffness at its node with the truth's coefficients
// (returned, at the truth's speed).
inline LinkCoefficients omit_coupling(ConcealedCase& c, size_t i) {
  const Link& l = c.truth.links[i];
  const LinkCoefficients at = l.at_speed(c.truth.speed_rpm);
  c.nominal.links.erase(c.nominal.links.begin() + static_cast<long>(i));
  c.physics = TruthPhysics{"coupling_stiffness",
                           {{"link", l.name}, {"node", l.node}},
                           {{"k", at[static_cast<size_t>(LinkCoef::kxx)]}, {"c", at[static_cast<size_t>(LinkCoef::cxx)]}}};
  c.note = "the drive-end coupling link (node " + std::to_string(l.node) + ") left out of the nominal model";
  return at;
}

}  // namespace concealed_detail

// One case: `machine` in concealed_machines(), `effect` in concealed_effects().
inline ConcealedCase concealed_case(const PlantModel& reference, const std::string& machine, const std::string& effect) {
  using nlohmann::json;
  using concealed_detail::link_named;
  const PlantModel plant = concealed_machine(reference, machine);
  const bool ref = machine == "reference_pump";
  ConcealedCase c;
  c.name = machine + "/" + effect;
  c.machine = machine;
  c.effect = effect;
  c.nominal = plant;
  c.truth = plant;
  const auto me = std::find(concealed_machines().begin(), concealed_machines().end(), machine) - concealed_machines().begin();
  const auto ef = std::find(concealed_effects().begin(), concealed_effects().end(), effect) - concealed_effects().begin();
  const unsigned seed = 1800u + 10u * static_cast<unsigned>(me) + static_cast<unsigned>(ef);
  if (effect == "gyroscopic_omitted") {
    json ip = json::object();
    double total = 0.0;
    for (auto& d : c.nominal.disks) {
      ip[d.name] = d.ip_kg_m2;
      total += d.ip_kg_m2;
      d.ip_kg_m2 = 0.0;
    }
    c.physics = TruthPhysics{"gyroscopic", {{"disks", "all"}}, {{"Ip", ip}, {"Ip_total", total}}};
    c.note = "every disk's polar inertia Ip left out of the nominal model";
  } else if (effect == "added_mass") {
    // Fluid and deposit mass with its own diametral inertia at a disk: the
    // thrust disk of the reference pump, the impeller of the second pump,
    // both beyond the disk-mass update bound (x1.1).
    const int node = ref ? 6 : 10;
    const double kg = ref ? 1.2 : 1.6, id = ref ? 0.006 : 0.005;
    c.truth.disks.push_back({"concealed_mass", node, kg, id, 0.0});
    c.physics = TruthPhysics{"added_mass", {{"node", node}}, {{"kg", kg}, {"Id", id}}};
    c.note = "an added mass with diametral inertia at a disk node";
  } else if (effect == "seal_cross_coupling") {
    const std::string link = ref ? "balance_piston" : "back_wear_ring";
    const double k = ref ? 80000.0 : 45000.0, cc = ref ? 300.0 : 110.0;
    Link& l = c.truth.links[link_named(c.truth, link)];
    concealed_detail::add_cross_coupling(l, k, cc);
    c.physics = TruthPhysics{"seal_cross_coupling", {{"link", link}, {"node", l.node}}, {{"k", k}, {"c", cc}}};
    c.note = "seal cross-coupling (kxy = -kyx, cxy = -cyx) added at one seal";
  } else if (effect == "coupling_omitted") {
    concealed_detail::omit_coupling(c, link_named(plant, "coupling"));
  } else if (effect == "absorber") {
    // 6 % of the rotor mass at the balance-piston node, 1 % damping, tuned
    // a little below bending 2 (reference 596/614 Hz, second pump about
    // 500 Hz), where the node moves: its own mode stands out of the noise
    // (tuned between the modes, where mid-rotor barely moves, it would hide
    // behind a mass effect; concealed_cases_test.cc checks it does not).
    const double mr = plant.rotor_mass_kg();
    c.absorber = ref ? Absorber::tuned(12, 0.06 * mr, 520.0, 0.01) : Absorber::tuned(12, 0.06 * mr, 430.0, 0.01);
    c.note = "a tuned mass on a spring at a mid-rotor node (x and y): not expressible in the plant format";
  } else {
    throw std::invalid_argument("concealed_case: unknown effect " + effect);
  }
  concealed_detail::record(c, seed);
  return c;
}

// Every case, machine-major in the order of concealed_machines() and concealed_effects().
inline std::vector<ConcealedCase> concealed_cases(const PlantModel& reference) {
  std::vector<ConcealedCase> out;
  for (const auto& m : concealed_machines())
    for (const auto& e : concealed_effects()) out.push_back(concealed_case(reference, m, e));
  return out;
}

// Variations (issue 18: unseen cases). One concealed effect on `machine`
// (concealed_variant_machines()) with its place and size drawn by a seeded
// RNG (std::mt19937_64 on seed_seq{seed, machine, effect}, uniform draws
// from its raw bits, so a seed gives the same case everywhere) from:
//
//   gyroscopic_omitted  nominal Ip = 0; the truth's Ip of each disk x U(0.6, 1.0)
//   added_mass          a disk {kg, Id, Ip = 0} at a node drawn from the disk
//                       nodes that carry no actuator and the nodes at least 2
//                       away from every radial sensor and actuator node;
//                       kg = rotor mass x log-U(0.5 %, 10 %); Id = kg r^2 / 4 x
//                       U(0, 1), the thin disk of r = 1.5 x the machine's
//                       largest disk radius (sqrt(2 Ip / m)): fluid or deposit
//                       reaching a little beyond the disks
//   seal_cross_coupling a link of kind seal or balance_piston drawn;
//                       kxy = -kyx += k, cxy = -cyx += c with k / K_direct
//                       U(0.1, 0.5), c / C_direct U(0.05, 0.4), both > 0 as a
//                       seal's swirl gives (forward whirl destabilised)
//   coupling_omitted    nominal without the coupling link; the truth's
//                       coupling kxx = kyy x log-U(0.5, 2)
//   absorber            node drawn from the middle third of the rotor (by
//                       position); m = rotor mass x U(2 %, 8 %), zeta U(0.5 %,
//                       3 %), tuned U(150, 900) Hz
//
// and the noise seed. A draw whose concealment does not show beyond the
// noise (chi2 per value of the nominal model on the recording <= 1.5, the
// rule of concealed_cases_test.cc) or, for the absorber, whose own mode
// does not stand out of the best plain mass (absorber_excess <= 20, the
// rule of AbsorberModeIsNotAnAddedMass, against the best-fitting mass
// rather than the same mass) is discarded and drawn again from the same
// RNG; `discarded` counts them (throws after 200).
inline ConcealedCase concealed_case_variant(const PlantModel& reference, const std::string& machine, const std::string& effect,
                                            unsigned seed) {
  using nlohmann::json;
  const auto& ms = concealed_variant_machines();
  const auto& es = concealed_effects();
  const auto me = std::find(ms.begin(), ms.end(), machine) - ms.begin();
  const auto ef = std::find(es.begin(), es.end(), effect) - es.begin();
  if (me == static_cast<long>(ms.size()) || ef == static_cast<long>(es.size()))
    throw std::invalid_argument("concealed_case_variant: unknown case " + machine + "/" + effect);
  std::seed_seq sq{seed, static_cast<unsigned>(me), static_cast<unsigned>(ef)};
  std::mt19937_64 rng(sq);
  auto u01 = [&rng] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  auto uni = [&](double lo, double hi) { return lo + (hi - lo) * u01(); };
  auto log_uni = [&](double lo, double hi) { return lo * std::pow(hi / lo, u01()); };
  auto pick = [&](size_t n) { return std::min(n - 1, static_cast<size_t>(u01() * static_cast<double>(n))); };
  const PlantModel plant = concealed_machine(reference, machine);
  const double mr = plant.rotor_mass_kg();
  const auto pos = plant.node_positions_m();
  for (int attempt = 0; attempt < 200; ++attempt) {
    ConcealedCase c;
    c.name = machine + "/" + effect + "#" + std::to_string(seed);
    c.machine = machine;
    c.effect = effect;
    c.seed = seed;
    c.discarded = attempt;
    c.nominal = plant;
    c.truth = plant;
    if (effect == "gyroscopic_omitted") {
      json ip = json::object();
      double total = 0.0, total0 = 0.0;
      for (size_t k = 0; k < plant.disks.size(); ++k) {
        c.truth.disks[k].ip_kg_m2 *= uni(0.6, 1.0);
        ip[plant.disks[k].name] = c.truth.disks[k].ip_kg_m2;
        total += c.truth.disks[k].ip_kg_m2;
        total0 += plant.disks[k].ip_kg_m2;
        c.nominal.disks[k].ip_kg_m2 = 0.0;
      }
      c.physics = TruthPhysics{"gyroscopic", {{"disks", "all"}}, {{"Ip", ip}, {"Ip_total", total}}};
      c.note = "every disk's polar inertia Ip left out of the nominal model; the truth's Ip scaled per disk";
      c.drawn = concealed_detail::fmt("Ip total %.4f kg m^2 (x%.2f of the design)", total, total / total0);
    } else if (effect == "added_mass") {
      std::vector<int> radial;
      for (const auto* v : {&plant.sensors, &plant.actuators})
        for (const auto& s : *v)
          if (!s.is_axial() && s.node) radial.push_back(*s.node);
      std::vector<int> nodes;
      for (int n = 0; n < plant.node_count(); ++n) {
        bool away = true, disk = false, actuated = false;
        for (int b : radial) away = away && std::abs(n - b) >= 2;
        for (const auto& d : plant.disks) disk = disk || d.node == n;
        for (const auto& a : plant.actuators) actuated = actuated || (a.node && *a.node == n);
        if (away || (disk && !actuated)) nodes.push_back(n);
      }
      double r = 0.0;
      for (const auto& d : plant.disks)
        if (d.m_kg > 0) r = std::max(r, std::sqrt(2 * d.ip_kg_m2 / d.m_kg));
      const int node = nodes[pick(nodes.size())];
      const double kg = mr * log_uni(0.005, 0.10);
      const double id_thin = kg * std::pow(1.5 * r, 2) / 4;
      const double id = id_thin * u01();
      c.truth.disks.push_back({"concealed_mass", node, kg, id, 0.0});
      // Id_floor: below a quarter of the thin-disk value the 30 % of
      // concealed_verdict is taken of that quarter (a nearly point-like
      // mass: its Id's relative error is meaningless, docs/explain.md).
      c.physics = TruthPhysics{"added_mass", {{"node", node}}, {{"kg", kg}, {"Id", id}, {"Id_floor", 0.25 * id_thin}}};
      c.note = "an added mass with diametral inertia at a drawn node";
      c.drawn = concealed_detail::fmt("node %d, %.3f kg (%.2f %% of the rotor), Id %.5f (%.2f x thin disk)", node, kg, 100 * kg / mr, id, id / id_thin);
    } else if (effect == "seal_cross_coupling") {
      std::vector<size_t> seals;
      for (size_t i = 0; i < plant.links.size(); ++i)
        if (plant.links[i].kind == "seal" || plant.links[i].kind == "balance_piston") seals.push_back(i);
      const size_t i = seals[pick(seals.size())];
      Link& l = c.truth.links[i];
      const LinkCoefficients at = l.at_speed(plant.speed_rpm);
      const double kd = at[static_cast<size_t>(LinkCoef::kxx)], cd = at[static_cast<size_t>(LinkCoef::cxx)];
      const double kr = uni(0.1, 0.5), cr = uni(0.05, 0.4);
      concealed_detail::add_cross_coupling(l, kr * kd, cr * cd);
      c.physics = TruthPhysics{"seal_cross_coupling", {{"link", l.name}, {"node", l.node}}, {{"k", kr * kd}, {"c", cr * cd}}};
      c.note = "seal cross-coupling (kxy = -kyx, cxy = -cyx) added at a drawn seal";
      c.drawn = concealed_detail::fmt("%s (node %d), k %.0f (%.2f K), c %.1f (%.2f C)", l.name.c_str(), l.node, kr * kd, kr, cr * cd, cr);
    } else if (effect == "coupling_omitted") {
      const size_t i = concealed_detail::link_named(plant, "coupling");
      const double f = log_uni(0.5, 2.0);
      Link& l = c.truth.links[i];
      for (LinkCoef k : {LinkCoef::kxx, LinkCoef::kyy}) {
        l.coef[static_cast<size_t>(k)] *= f;
        for (auto& row : l.table)
          if (row.values[static_cast<size_t>(k)]) *row.values[static_cast<size_t>(k)] *= f;
      }
      const LinkCoefficients at = concealed_detail::omit_coupling(c, i);
      c.drawn = concealed_detail::fmt("coupling k %.3g N/m (x%.2f of the design)", at[static_cast<size_t>(LinkCoef::kxx)], f);
    } else {  // absorber
      const double len = pos.back() - pos.front();
      std::vector<int> nodes;
      for (int n = 0; n < plant.node_count(); ++n)
        if (pos[static_cast<size_t>(n)] - pos.front() >= len / 3 && pos[static_cast<size_t>(n)] - pos.front() <= 2 * len / 3) nodes.push_back(n);
      const int node = nodes[pick(nodes.size())];
      const double frac = uni(0.02, 0.08), zeta = uni(0.005, 0.03), f = uni(150.0, 900.0);
      c.absorber = Absorber::tuned(node, frac * mr, f, zeta);
      c.note = "a tuned mass on a spring at a drawn mid-rotor node (x and y): not expressible in the plant format";
      c.drawn = concealed_detail::fmt("node %d, %.3f kg (%.1f %%), tuned %.1f Hz, zeta %.2f %%", node, frac * mr, 100 * frac, f, 100 * zeta);
    }
    concealed_detail::record(c, static_cast<unsigned>(rng() & 0xffffffffu));
    const FrfComparison before = compare_frf(model_frf_like(c.nominal, c.measured), c.measured);
    c.chi2_per_value_before = before.chi2 / before.chi2_lines;
    if (c.absorber) c.drawn += concealed_detail::fmt("; mode %.0f Hz, excess %.0f over %.3f kg plain", c.extra_mode_hz, c.absorber_excess, c.best_plain_mass_kg);
    if (c.chi2_per_value_before <= 1.5 || (c.absorber && c.absorber_excess <= 20.0)) continue;
    return c;
  }
  throw std::runtime_error("concealed_case_variant: no draw of " + machine + "/" + effect + " shows beyond the noise in 200");
}

// What explain must say on a case (issue 18's target); an empty list when it
// does. Tolerances: with 1 % noise on 25 entries x 1000 lines a parameter
// whose effect is several times the noise floor is determined to well under
// 1 % (explain's own sd says so), so the bands below are for the model form
// the fit cannot resolve, not for noise:
//  - added_mass: kg 10 %; Id 30 % (it acts through the mode shapes' slopes
//    squared, an order weaker than the mass, and trades with the mass's
//    node on the discrete mesh);
//  - seal_cross_coupling: k 10 %; c 25 % (c w is below k over most of the
//    band, so the data hold c less tightly);
//  - coupling_stiffness: the improved model has a link at the truth's node
//    with kxx = kyy within 15 % (its damping, 20-30 N s/m, is a loss factor
//    of a few % and is not checked);
//  - gyroscopic: the improved model's total Ip within 20 % (which disk
//    carries how much is weakly determined: a disk at a node of a mode's
//    slope adds nothing to that mode's split);
// nothing else named, no parameter updated (the truth changes none), no
// unexplained band, NRMSE after <= 1.1 x the noise floor. The absorber: no
// physics, no update, an unexplained band containing its mode's line.
inline std::vector<std::string> concealed_verdict(const ConcealedCase& c, const ExplainResult& r) {
  std::vector<std::string> fail;
  auto within = [](double got, double want, double rel) { return std::abs(got - want) <= rel * std::abs(want); };
  auto num = [](const nlohmann::json& j, const char* key) {
    return j.is_object() && j.contains(key) && j[key].is_number() ? j[key].get<double>() : std::nan("");
  };
  std::string named;
  for (const auto& e : r.explanations) named += " " + e.physics + " " + e.location.dump() + " " + e.parameters.dump() + ";";
  if (!r.updated_parameters.empty()) {
    std::string u;
    for (const auto& p : r.updated_parameters) u += " " + p.path + " " + std::to_string(p.from) + " -> " + std::to_string(p.to) + ";";
    fail.push_back("parameters updated, the truth changes none:" + u);
  }
  if (!c.physics) {
    if (!r.explanations.empty()) fail.push_back("physics claimed for an effect outside the catalogue:" + named);
    bool located = false;
    for (const auto& u : r.unexplained) located |= u.band_lo_hz <= c.extra_mode_hz && c.extra_mode_hz <= u.band_hi_hz;
    if (!located) {
      std::string bands;
      for (const auto& u : r.unexplained) bands += " " + std::to_string(u.band_lo_hz) + "-" + std::to_string(u.band_hi_hz) + " Hz;";
      fail.push_back("no unexplained band contains the absorber's mode at " + std::to_string(c.extra_mode_hz) + " Hz (unexplained:" +
                     (bands.empty() ? std::string(" none") : bands) + ")");
    }
    return fail;
  }
  const TruthPhysics& t = *c.physics;
  const Explanation* e = nullptr;
  for (const auto& x : r.explanations)
    if (x.physics == t.physics) e = &x;
  if (r.explanations.size() != 1 || !e) fail.push_back("named" + (named.empty() ? std::string(" nothing") : named) + " instead of " + t.physics + " alone");
  if (e) {
    const nlohmann::json& p = e->parameters;
    if (t.physics == "added_mass") {
      if (e->location.value("node", -1) != t.location["node"].get<int>()) fail.push_back("added_mass at " + e->location.dump() + ", truth " + t.location.dump());
      if (!within(num(p, "kg"), t.parameters["kg"], 0.10)) fail.push_back("added_mass kg " + p.dump() + ", truth " + t.parameters.dump() + " (10 %)");
      const double id = t.parameters["Id"], floor = t.parameters.value("Id_floor", 0.0);  // Id_floor: variants only
      if (!(std::abs(num(p, "Id") - id) <= 0.30 * std::max(id, floor)))
        fail.push_back("added_mass Id " + p.dump() + ", truth " + t.parameters.dump() + " (30 %)");
    } else if (t.physics == "seal_cross_coupling") {
      if (e->location.value("link", std::string()) != t.location["link"].get<std::string>())
        fail.push_back("seal_cross_coupling at " + e->location.dump() + ", truth " + t.location.dump());
      if (!within(num(p, "k"), t.parameters["k"], 0.10)) fail.push_back("seal_cross_coupling k " + p.dump() + ", truth " + t.parameters.dump() + " (10 %)");
      if (!within(num(p, "c"), t.parameters["c"], 0.25)) fail.push_back("seal_cross_coupling c " + p.dump() + ", truth " + t.parameters.dump() + " (25 %)");
    } else if (t.physics == "coupling_stiffness") {
      const int node = t.location["node"].get<int>();
      if (e->location.value("node", -1) != node) fail.push_back("coupling_stiffness at " + e->location.dump() + ", truth " + t.location.dump());
      double k = std::nan("");
      for (const auto& l : r.improved.plant.links)
        if (l.node == node) k = l.at_speed(r.improved.plant.speed_rpm)[static_cast<size_t>(LinkCoef::kxx)];
      if (!within(k, t.parameters["k"], 0.15))
        fail.push_back("improved model's link at node " + std::to_string(node) + ": kxx " + std::to_string(k) + ", truth " + t.parameters.dump() + " (15 %)");
    } else if (t.physics == "gyroscopic") {
      double total = 0.0;
      for (const auto& d : r.improved.plant.disks) total += d.ip_kg_m2;
      if (!within(total, t.parameters["Ip_total"], 0.20))
        fail.push_back("improved model's total Ip " + std::to_string(total) + ", truth " + t.parameters.dump() + " (20 %)");
    }
  }
  if (!r.unexplained.empty()) fail.push_back(std::to_string(r.unexplained.size()) + " unexplained band(s) left");
  if (!(r.nrmse_after <= 1.1 * r.noise_floor_nrmse))
    fail.push_back("NRMSE after " + std::to_string(r.nrmse_after) + " > 1.1 x noise floor " + std::to_string(r.noise_floor_nrmse));
  return fail;
}

}  // namespace ambdiag::testing
