// A four-stage pump in active magnetic bearings, for identification tests
// of whirl pairs (issue 18): a stepped shaft 1.32 m long with four
// impellers between the bearings, a thrust disk outboard of bearing A and a
// balance piston inboard of bearing B. The AMBs are bearing links (their
// closed-loop stiffness and damping); each stage has a wear ring (a fluid
// seal with cross-coupled stiffness, `kxy = -kyx`, and heavy direct damping)
// that splits the first bending mode into a backward and a forward whirl a
// few percent apart and damps both by 10-12 %. A housing resonance on plane
// B (x and y) lies a little above that pair.
// Sensors at the bearing planes (A, B; x and y), actuators at the magnets,
// and an axial pair: a 5 x 5 FRF matrix like the shared pump's.
#pragma once

#include <string>

#include "ambdiag/core/plant_model.h"

namespace ambdiag::testing {

inline constexpr double kFourStagePumpRpm = 2980.0;

inline PlantModel four_stage_pump() {
  PlantModel p;
  p.name = "four-stage pump in AMBs (whirl pair test machine)";
  p.speed_rpm = kFourStagePumpRpm;
  p.materials["steel"] = Material{2.11e11, 8.12e10, 7810.0};
  // 24 elements of 55 mm: journals 60 mm, the stage section 75 mm.
  for (int i = 0; i < 24; ++i) {
    const double od_m = (i >= 5 && i < 19) ? 0.115 : 0.085;
    p.shaft.push_back(ShaftElement{0.055, od_m, 0.0, "steel", 0.0});
  }
  p.disks.push_back(Disk{"thrust_disk", 1, 3.5, 0.0070, 0.0135});
  p.disks.push_back(Disk{"amb_A_laminations", 3, 6.0, 0.0090, 0.0100});
  const int impeller_nodes[4] = {8, 11, 14, 17};
  for (int s = 0; s < 4; ++s)
    p.disks.push_back(Disk{"impeller_" + std::to_string(s + 1), impeller_nodes[s], 5.0, 0.0120, 0.0230});
  p.disks.push_back(Disk{"amb_B_laminations", 22, 6.0, 0.0090, 0.0100});
  auto link = [](const std::string& name, const std::string& kind, int node, double k, double kxy, double c,
                 double cxy) {
    Link l;
    l.name = name;
    l.kind = kind;
    l.node = node;
    l.coef[static_cast<int>(LinkCoef::kxx)] = l.coef[static_cast<int>(LinkCoef::kyy)] = k;
    l.coef[static_cast<int>(LinkCoef::kxy)] = kxy;
    l.coef[static_cast<int>(LinkCoef::kyx)] = -kxy;
    l.coef[static_cast<int>(LinkCoef::cxx)] = l.coef[static_cast<int>(LinkCoef::cyy)] = c;
    l.coef[static_cast<int>(LinkCoef::cxy)] = cxy;
    l.coef[static_cast<int>(LinkCoef::cyx)] = -cxy;
    return l;
  };
  p.links.push_back(link("amb_A", "bearing", 3, 4.0e5, 0.0, 8.0e2, 0.0));
  p.links.push_back(link("amb_B", "bearing", 22, 4.0e5, 0.0, 8.0e2, 0.0));
  for (int s = 0; s < 4; ++s)
    p.links.push_back(link("wear_ring_" + std::to_string(s + 1), "seal", impeller_nodes[s] + 1, 8.0e5, 6.0e5,
                           19000.0, 3000.0));
  p.links.push_back(link("balance_piston", "balance_piston", 19, 4.0e5, 1.0e5, 2500.0, 100.0));
  p.links.push_back(link("coupling", "coupling", 0, 8.0e5, 0.0, 20.0, 0.0));
  p.housings.push_back({"housing_B", "B", {"x", "y"}, 296.0, 0.04, 70.0});
  p.axial = AxialModel{std::nullopt, 1.5e6, 3000.0, {}};
  p.structural_damping = StructuralDamping{StructuralDamping::Kind::modal, 0.0075};
  const char* planes[2] = {"A", "B"};
  const int sensor_nodes[2] = {5, 19}, magnet_nodes[2] = {3, 22};
  for (int b = 0; b < 2; ++b) {
    for (char d : {'x', 'y'}) {
      p.sensors.push_back(MeasurementPoint{std::string("x") + planes[b] + d, planes[b], sensor_nodes[b], d});
      p.actuators.push_back(
          MeasurementPoint{std::string("f") + planes[b] + d, planes[b], magnet_nodes[b], d});
    }
  }
  p.sensors.push_back(MeasurementPoint{"xZ", "Z", std::nullopt, 'z'});
  p.actuators.push_back(MeasurementPoint{"fZ", "Z", std::nullopt, 'z'});
  validate_plant(p);
  return p;
}

}  // namespace ambdiag::testing
