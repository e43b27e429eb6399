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
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/LU>
#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/explain/explain.h"
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
  std::string note;            // the case in words
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

inline PlantModel concealed_machine(const PlantModel& reference, const std::string& machine) {
  if (machine == "reference_pump") return reference;
  if (machine == "second_pump") return second_pump(reference);
  throw std::invalid_argument("concealed_machine: unknown machine " + machine);
}

namespace concealed_detail {

inline size_t link_named(const PlantModel& p, const std::string& name) {
  for (size_t i = 0; i < p.links.size(); ++i)
    if (p.links[i].name == name) return i;
  throw std::invalid_argument("no link " + name + " in " + p.name);
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

inline AbsorberReceptance absorber_receptance(const PlantModel& plant, double speed_rpm, const FrfData& like,
                                              const Absorber& a) {
  using cd = std::complex<double>;
  std::vector<double> omega;
  for (double f : like.freq_hz) omega.push_back(2 * M_PI * f);
  StructuralDampingOptions damping;  // as synthesize_frf: omega_max from the highest line
  damping.omega_max_rad_per_s = omega.back();
  const RotorSystem sys = assemble_rotor(plant, speed_rpm, damping);
  const ambdiag::detail::RotorReceptance g(sys, omega);
  std::vector<int> rows, cols, row_of, col_of;
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
    row_of.push_back(lateral ? index_of(rows, lateral_dof(*s->node, s->dir)) : -1);
    col_of.push_back(lateral ? index_of(cols, lateral_dof(*u->node, u->dir)) : -1);
  }
  const std::vector<int> dofs = {lateral_dof(a.node, 'x'), lateral_dof(a.node, 'y')};
  const Eigen::MatrixXcd g_sa = g.block(rows, cols), g_su = g.block(rows, dofs), g_uu = g.block(dofs, dofs),
                         g_ua = g.block(dofs, cols);
  const auto nr = static_cast<Eigen::Index>(rows.size()), nc = static_cast<Eigen::Index>(cols.size());
  AbsorberReceptance out;
  out.g.assign(like.entries.size(), std::vector<cd>(omega.size(), cd(0.0, 0.0)));
  out.g_abs = out.g;
  for (size_t l = 0; l < omega.size(); ++l) {
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
    const cd z = a.z(omega[l]);
    const Eigen::Matrix2cd lhs = Eigen::Matrix2cd::Identity() + z * uu;
    const Eigen::MatrixXcd changed = sa - su * lhs.partialPivLu().solve(z * ua);
    for (size_t e = 0; e < like.entries.size(); ++e) {
      if (row_of[e] < 0) continue;
      out.g[e][l] = sa(row_of[e], col_of[e]);
      out.g_abs[e][l] = changed(row_of[e], col_of[e]);
    }
  }
  return out;
}

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
    const size_t i = link_named(plant, "coupling");
    const Link& l = plant.links[i];
    const LinkCoefficients at = l.at_speed(plant.speed_rpm);
    c.nominal.links.erase(c.nominal.links.begin() + static_cast<long>(i));
    c.physics = TruthPhysics{"coupling_stiffness",
                             {{"link", l.name}, {"node", l.node}},
                             {{"k", at[static_cast<size_t>(LinkCoef::kxx)]}, {"c", at[static_cast<size_t>(LinkCoef::cxx)]}}};
    c.note = "the drive-end coupling link (node " + std::to_string(l.node) + ") left out of the nominal model";
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
  const std::vector<double> grid = frequency_grid(1.0, 1000.0, 1.0);
  c.measured = synthesize_frf(c.truth, c.truth.speed_rpm, grid, {FrfMethod::modal});
  c.measured.speed_rpm = c.truth.speed_rpm;
  if (c.absorber) {
    const AbsorberReceptance ar = absorber_receptance(c.truth, c.truth.speed_rpm, c.measured, *c.absorber);
    // Against the same mass fixed to the node (what the absorber looks like
    // below its tuning), the absorber's own mode: the line of the largest
    // change within 6 % of its tuning.
    const AbsorberReceptance rigid =
        absorber_receptance(c.truth, c.truth.speed_rpm, c.measured, Absorber{c.absorber->node, c.absorber->m_kg, 1e13, 0.0});
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
  }
  add_recording_noise(c.measured, 0.0, seed);
  return c;
}

// Every case, machine-major in the order of concealed_machines() and concealed_effects().
inline std::vector<ConcealedCase> concealed_cases(const PlantModel& reference) {
  std::vector<ConcealedCase> out;
  for (const auto& m : concealed_machines())
    for (const auto& e : concealed_effects()) out.push_back(concealed_case(reference, m, e));
  return out;
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
      if (!within(num(p, "Id"), t.parameters["Id"], 0.30)) fail.push_back("added_mass Id " + p.dump() + ", truth " + t.parameters.dump() + " (30 %)");
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
