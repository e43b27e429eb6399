// A generated test and benchmark rotor: a uniform solid steel shaft 1.5 m
// long, 60 mm thick, in `elements` equal Timoshenko elements (a multiple of
// 10), with three disks and two damped bearings at fixed fractions of the
// length, so the physical rotor is the same for every element count.
// Sensors at the bearings (A, B; x and y), actuators at the outer disks
// (x and y), and an axial sensor/actuator pair: a 5 x 5 FRF matrix.
#pragma once

#include <string>

#include "ambdiag/core/plant_model.h"

namespace ambdiag::testing {

struct GeneratedRotorOptions {
  bool isotropic_bearings = false;  // kxx = kyy (else kyy = 1.5 kxx)
  double zeta_structural = 0.005;   // modal structural damping (0: none)
};

inline PlantModel generated_rotor(int elements, const GeneratedRotorOptions& o = {}) {
  PlantModel p;
  p.name = "generated shaft, " + std::to_string(elements) + " elements";
  p.speed_rpm = 3000.0;
  p.materials["steel"] = Material{2.11e11, 8.12e10, 7810.0};
  const double length_m = 1.5, od_m = 0.06;
  for (int i = 0; i < elements; ++i) p.shaft.push_back(ShaftElement{length_m / elements, od_m, 0.0, "steel", 0.0});
  auto at = [&](int tenths) { return elements * tenths / 10; };
  p.disks.push_back(Disk{"disk_1", at(3), 8.0, 0.05, 0.09});
  p.disks.push_back(Disk{"disk_2", at(5), 12.0, 0.08, 0.15});
  p.disks.push_back(Disk{"disk_3", at(7), 8.0, 0.05, 0.09});
  const int bearing_nodes[2] = {at(1), at(9)};
  const char* planes[2] = {"A", "B"};
  for (int b = 0; b < 2; ++b) {
    Link l;
    l.name = std::string("bearing_") + planes[b];
    l.node = bearing_nodes[b];
    l.kind = "bearing";
    const double k = 2.0e7;
    l.coef[static_cast<int>(LinkCoef::kxx)] = k;
    l.coef[static_cast<int>(LinkCoef::kyy)] = o.isotropic_bearings ? k : 1.5 * k;
    l.coef[static_cast<int>(LinkCoef::cxx)] = 2.0e3;
    l.coef[static_cast<int>(LinkCoef::cyy)] = 2.0e3;
    p.links.push_back(l);
  }
  p.axial = AxialModel{std::nullopt, 1.0e6, 1.0e3, {}};
  if (o.zeta_structural > 0) p.structural_damping = StructuralDamping{StructuralDamping::Kind::modal, o.zeta_structural};
  for (int b = 0; b < 2; ++b) {
    for (char d : {'x', 'y'}) {
      p.sensors.push_back(MeasurementPoint{std::string("x") + planes[b] + d, planes[b], bearing_nodes[b], d});
      p.actuators.push_back(MeasurementPoint{std::string("f") + planes[b] + d, planes[b], b == 0 ? at(3) : at(7), d});
    }
  }
  p.sensors.push_back(MeasurementPoint{"xZ", "Z", std::nullopt, 'z'});
  p.actuators.push_back(MeasurementPoint{"fZ", "Z", std::nullopt, 'z'});
  return p;
}

}  // namespace ambdiag::testing
