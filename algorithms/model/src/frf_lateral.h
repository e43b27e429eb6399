// Lateral FRFs of a rotor system at angular frequencies w (rad/s); result
// rows are lines, column o * n_in + i is output o over input i. Private to
// the FRF synthesis; each fills the method, pole and timing fields of the
// report.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/algorithms/model/rotor_system.h"
#include "frf_terms.h"

namespace ambdiag::detail {

Eigen::MatrixXcd lateral_frf_direct(const RotorSystem& sys, const LateralMaps& maps, const std::vector<double>& w,
                                    FrfReport& report);
// Every eigenvalue of the first-order form (dense).
Eigen::MatrixXcd lateral_frf_modal(const RotorSystem& sys, const LateralMaps& maps, const std::vector<double>& w,
                                   FrfReport& report);
// Krylov reduced model (rotor_krylov.h).
Eigen::MatrixXcd lateral_frf_modal_krylov(const RotorSystem& sys, const LateralMaps& maps,
                                          const std::vector<double>& w, double tol, FrfReport& report);

// Seconds since `start` (steady clock), for the reports.
double seconds_since(double start_s);
double now_s();

}  // namespace ambdiag::detail
