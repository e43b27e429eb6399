// Lateral FRFs of a rotor system at angular frequencies w (rad/s); result
// rows are lines, column o * n_in + i is output o over input i. Private to
// the FRF synthesis.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "ambdiag/algorithms/rotor_system.h"
#include "frf_terms.h"

namespace ambdiag::detail {

Eigen::MatrixXcd lateral_frf_direct(const RotorSystem& sys, const LateralMaps& maps, const std::vector<double>& w);
Eigen::MatrixXcd lateral_frf_modal(const RotorSystem& sys, const LateralMaps& maps, const std::vector<double>& w);

}  // namespace ambdiag::detail
