// Pieces shared by the FRF synthesis methods: the lateral input/output maps
// and the closed-form housing and axial compliances.
#pragma once

#include <complex>
#include <vector>

#include <Eigen/Core>

#include "ambdiag/algorithms/model/rotor_system.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag::detail {

// Lateral measurement points as rows/columns in rotor coordinates.
struct LateralMaps {
  std::vector<int> sensor_index;    // index into plant.sensors of each lateral output
  std::vector<int> actuator_index;  // index into plant.actuators of each lateral input
  Eigen::MatrixXd c_out;            // outputs x coordinates
  Eigen::MatrixXd b_in;             // coordinates x inputs
};

LateralMaps lateral_maps(const PlantModel& plant, const RotorSystem& sys);

// Compliance that acts in parallel with the rotor between sensor s and
// actuator a (housings; the whole axial model for axial pairs), m/N, on
// every line of omega_rad_per_s.
std::vector<std::complex<double>> parallel_compliances(const PlantModel& plant, const MeasurementPoint& s,
                                                       const MeasurementPoint& a,
                                                       const std::vector<double>& omega_rad_per_s);

}  // namespace ambdiag::detail
