// The library of model corrections that `explain` (explain.h) chooses from:
// updates of parameters the plant model already has (within stated bounds)
// and physics the model may have left out, each a parameterised extension of
// the plant model with the signature it leaves in the FRF matrix.
//
//   physics                signature                               extension of the plant
//   housing_mode           resonance in the direct FRFs of one     housings[] (lateral plane) or
//                          plane and direction, no rotor mode      axial.housings[] (plane Z):
//                                                                  f_hz, zeta, m_kg
//   seal_cross_coupling    Hxy != -Hyx ... non-reciprocal cross    link kxy = -kyx += k,
//                          FRFs, forward/backward damping split    cxy = -cyx += c
//   added_mass             modes near a node lowered               disk {m, Id} added at a node
//   acquisition_delay      phase -w tau on every entry             PlantVariant::delay_s; in JSON
//                                                                  "acquisition": {"delay_s"}
//   sensor_noncollocation  anti-resonances of one plane move       sensors of a plane moved to
//                                                                  another node
//   coupling_stiffness     low modes shift (coupling end)          coupling link kxx = kyy scaled
//   stiffness_change       modes shift beyond the update bounds    link kxx = kyy scaled
//   gyroscopic             forward/backward split changes          every disk's Ip scaled
//   damping                peak heights change, not frequencies    link cxx = cyy or structural
//                                                                  zeta scaled beyond update bounds
//
// Parameter updates (bounds): link direct stiffness x[0.7, 1.3], link direct
// damping x[0.5, 2], a fluid seal's clearance (every coefficient of a link
// of kind seal or balance_piston, direct and cross-coupled K, C, M, x[0.5,
// 2]: they all go as 1 / clearance), disk mass and Id x[0.9, 1.1], housing
// f x[0.9, 1.1], zeta x[0.5, 2], m x[0.7, 1.3], axial k x[0.7, 1.3], axial c
// x[1/3, 3], structural damping zeta x[0.5, 2]. A scaled coefficient is
// scaled in the link's speed table too.
#pragma once

#include <complex>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/model/plant_frf_fit.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag {

inline const std::vector<std::string>& physics_names() {
  static const std::vector<std::string> names = {"housing_mode",          "seal_cross_coupling", "added_mass",
                                                 "acquisition_delay",     "sensor_noncollocation", "coupling_stiffness",
                                                 "stiffness_change",      "gyroscopic",          "damping"};
  return names;
}

// One changed value of the plant file, for `updated_parameters`.
struct ParameterChange {
  std::string path;  // e.g. "links[2].kxx", "axial.c", "housings[0].f_hz"
  double from = 0.0, to = 0.0;
};

struct Candidate {
  std::string id;        // unique, e.g. "housing_mode:A:xy@906"
  std::string direction_key;  // candidates that move the plant the same way at their start share it
  std::string physics;   // a physics_names() entry, or "parameter_update"
  bool is_update = false;
  bool touches_rotor = false;  // needs FE solves (else closed form)
  std::string signature;       // what it leaves in the FRFs, for the evidence text
  nlohmann::json location = nlohmann::json::object();
  std::vector<FitParameter> params;
  int screen_params = -1;  // parameters used by the linearised screening (-1: all)
  // Applies the candidate with values x to a variant (in place).
  std::function<void(const std::vector<double>& x, PlantVariant& v)> apply;
  // Reported parameters, e.g. {"f_hz": 906, "zeta": 0.017, "m_kg": 40}.
  std::function<nlohmann::json(const std::vector<double>& x)> describe;
  // Changes of existing values (updates), against the plant it was made for.
  std::function<std::vector<ParameterChange>(const std::vector<double>& x)> changes;
  // A change the plant format cannot express: a dynamic stiffness z(w, x)
  // added to the lateral x and y DOFs of node `impedance_node` (to
  // K - w^2 M + j w C). Evaluated only on the low-rank model of the rotor
  // (explain_screen.h), where it is exact; `apply` leaves the plant alone.
  int impedance_node = -1;
  std::function<std::complex<double>(double omega_rad_per_s, const std::vector<double>& x)> node_impedance;
};

// What the candidate generator looks at: the weighted residual of the
// current model per entry and line, and where it is large.
struct ResidualView {
  const FrfData* measured = nullptr;
  std::vector<std::vector<std::complex<double>>> model_h;  // current model, all lines
  std::vector<std::vector<double>> sigma;
};

// Updates of existing parameters of `plant` (bounds above).
std::vector<Candidate> update_candidates(const PlantModel& plant);
// Physics candidates proposed from the signatures in the residual (housing
// modes start at the residual's peaks; a delay at the phase slope).
std::vector<Candidate> physics_candidates(const PlantModel& plant, const ResidualView& view);

// Not in the catalogue, a locator for what it cannot express: a mass m on
// a spring and damper tuned to f_hz with damping ratio zeta, attached to
// the rotor at `node` in x and y (a dynamic absorber, an attached part with
// a resonance of its own): z(w) = -w^2 m (k + j w c) / (k + j w c - w^2 m),
// k = m (2 pi f)^2, c = 2 zeta m (2 pi f). Parameters f_hz in [f_lo_hz,
// f_hi_hz], zeta, kg.
Candidate resonant_attachment(const PlantModel& plant, int node, double f_lo_hz, double f_hi_hz);

// The same physics at neighbouring places (added mass up to two nodes
// either side), for refining a discrete location after the other parameters settled.
std::vector<Candidate> neighbour_candidates(const PlantModel& plant, const Candidate& c);

// Serialises a variant as a plant JSON document (the delay as the
// extension "acquisition": {"delay_s"}, which the plant reader ignores and
// read_variant understands).
nlohmann::json variant_to_json(const PlantVariant& v);
PlantVariant variant_from_json(const nlohmann::json& doc);

}  // namespace ambdiag
