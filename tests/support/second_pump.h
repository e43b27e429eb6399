// A second machine for fleet tests: the shared reference pump
// (reference_pump/plant.json, read at test time, never copied) turned into a
// clearly different pump, as a fleet of one pump type would not exercise
// what a plant model is allowed to vary:
//  - a longer (x 1.25) and thicker (x 1.2) shaft, so other frequencies and
//    mode shapes (bending 1 near 150 Hz instead of 188 Hz);
//  - other disk masses and inertias, the impeller one node further left;
//  - a 60 Hz drive: nominal 3560 rpm (the reference runs at 2950 rpm);
//  - three fluid-seal links instead of two: the impeller's front wear ring
//    (kind `seal`, named `impeller_seal` like the reference's, so that the
//    simulator's and the diagnosis's `impeller_seal_wear` mean it), a back
//    wear ring (kind `seal` too: a second link of that kind), and the
//    balance piston, with other coefficients, all given by speed tables up
//    to 4200 rpm so the speed spread stays inside the tables;
//  - a housing resonance on both bearing planes, other coupling and axial
//    stiffness.
// Valid per ../shared/specs/plant-model.md (validate_plant is called).
#pragma once

#include <cmath>
#include <initializer_list>
#include <string>

#include "ambdiag/core/plant_model.h"

namespace ambdiag::testing {

inline constexpr double kSecondPumpRpm = 3560.0;

namespace detail {

// A fluid-seal link whose stiffnesses grow with rpm^2 and damping linearly
// from 15 % at standstill (the law of the reference pump's tables, which
// are Childs-type short-seal coefficients), given at the nominal speed
// `rpm0`, tabulated at `table_rpm` (strictly increasing).
inline Link fluid_link(const std::string& name, const std::string& kind, int node, double k, double k_cross,
                       double c, double c_cross, double m, double rpm0 = kSecondPumpRpm,
                       std::initializer_list<double> table_rpm = {0.0, 1000.0, 2000.0, 3000.0, kSecondPumpRpm, 4200.0}) {
  Link l;
  l.name = name;
  l.kind = kind;
  l.node = node;
  auto coef_at = [&](double rpm) {
    const double s = rpm / rpm0;
    LinkCoefficients v{};
    v[static_cast<int>(LinkCoef::kxx)] = v[static_cast<int>(LinkCoef::kyy)] = k * s * s;
    v[static_cast<int>(LinkCoef::kxy)] = k_cross * s * s;
    v[static_cast<int>(LinkCoef::kyx)] = -k_cross * s * s;
    v[static_cast<int>(LinkCoef::cxx)] = v[static_cast<int>(LinkCoef::cyy)] = c * (0.15 + 0.85 * s);
    v[static_cast<int>(LinkCoef::cxy)] = c_cross * s;
    v[static_cast<int>(LinkCoef::cyx)] = -c_cross * s;
    v[static_cast<int>(LinkCoef::mxx)] = v[static_cast<int>(LinkCoef::myy)] = m;
    return v;
  };
  l.coef = coef_at(rpm0);
  for (double rpm : table_rpm) {
    LinkTableRow row;
    row.rpm = rpm;
    const LinkCoefficients v = coef_at(rpm);
    for (int i = 0; i < kLinkCoefCount; ++i)
      if (i != static_cast<int>(LinkCoef::mxx) && i != static_cast<int>(LinkCoef::myy)) row.values[static_cast<size_t>(i)] = v[static_cast<size_t>(i)];
    l.table.push_back(row);
  }
  return l;
}

inline Link plain_link(const std::string& name, const std::string& kind, int node, double k, double c) {
  Link l;
  l.name = name;
  l.kind = kind;
  l.node = node;
  l.coef[static_cast<int>(LinkCoef::kxx)] = l.coef[static_cast<int>(LinkCoef::kyy)] = k;
  l.coef[static_cast<int>(LinkCoef::cxx)] = l.coef[static_cast<int>(LinkCoef::cyy)] = c;
  return l;
}

}  // namespace detail

// The second machine made from the reference pump's model (`reference` is
// that file read, so the materials, element count, sensor and actuator
// layout are the reference's and a change of the shared file shows here).
inline PlantModel second_pump(const PlantModel& reference) {
  PlantModel p = reference;
  p.name = "second pump: longer, thicker shaft, 60 Hz drive, three fluid seals (test fleet)";
  p.speed_rpm = kSecondPumpRpm;
  for (auto& e : p.shaft) {
    e.length_m *= 1.25;
    e.od_m *= 1.2;
    e.id_m *= 1.2;
  }
  // Disks: bigger magnets' laminations, a heavier thrust disk, a heavier
  // impeller one node further towards bearing A.
  p.disks.clear();
  p.disks.push_back({"amb_A_laminations", 3, 7.4, 0.0125, 0.0138});
  p.disks.push_back({"thrust_disk", 6, 3.1, 0.0060, 0.0115});
  p.disks.push_back({"impeller", 10, 3.4, 0.0052, 0.0088});
  p.disks.push_back({"amb_B_laminations", 19, 7.4, 0.0125, 0.0138});
  p.links.clear();
  p.links.push_back(detail::fluid_link("impeller_seal", "seal", 9, 3.0e5, 3.4e4, 650.0, 95.0, 1.0));
  p.links.push_back(detail::fluid_link("back_wear_ring", "seal", 11, 1.8e5, 2.1e4, 420.0, 60.0, 0.6));
  p.links.push_back(detail::fluid_link("balance_piston", "balance_piston", 13, 4.2e5, 7.0e4, 3600.0, 120.0, 3.5));
  p.links.push_back(detail::plain_link("mechanical_seal_1", "mechanical_seal", 8, 1.1e5, 1800.0));
  p.links.push_back(detail::plain_link("mechanical_seal_2", "mechanical_seal", 15, 1.1e5, 1800.0));
  p.links.push_back(detail::plain_link("coupling", "coupling", 0, 1.2e6, 30.0));
  p.housings.clear();
  p.housings.push_back({"housing_A", "A", {"x", "y"}, 380.0, 0.05, 75.0});
  p.housings.push_back({"housing_B", "B", {"x", "y"}, 520.0, 0.04, 90.0});
  if (p.axial) {
    p.axial->m_kg.reset();  // computed from the new shaft and disks
    p.axial->k_n_per_m = 1.6e6;
    p.axial->c_ns_per_m = 3200.0;
  }
  validate_plant(p);
  return p;
}

}  // namespace ambdiag::testing
