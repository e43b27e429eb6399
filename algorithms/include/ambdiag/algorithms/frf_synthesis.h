// Compliance FRF matrix of a plant model: H[o][i](f) = x_o / f_i in m/N for
// every sensor o and actuator i, at any frequency grid.
//
// Lateral entries come from the rotor system (rotor_system.h), computed
//  - direct: x = Cout (K - w^2 M + j w C)^-1 B f, with a sparse complex LU
//    (UMFPACK; symbolic analysis once, numeric factorization per line) and
//    the low-rank structural damping added by the Woodbury identity; cost
//    per line linear in the number of elements for a shaft;
//  - modal: superposition over the eigenvalues of the first-order form,
//    H(w) = sum_k (Cs v_k)(u_k^T Bs) / (j w - lambda_k), exact up to round-off
//    when all modes are kept (dense eigen-decomposition: small or reduced
//    models).
// Housing resonances add 1 / (m (w0^2 - w^2 + 2 j zeta w0 w)) to every entry
// whose sensor and actuator share its plane and direction; the axial entry is
// 1 / (k - w^2 m + j w c) plus the axial housings; lateral-axial entries are 0.
#pragma once

#include <vector>

#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag {

enum class FrfMethod { direct, modal };

struct FrfSynthesisOptions {
  FrfMethod method = FrfMethod::direct;
};

// Throws InputError if the model has no sensors or actuators, a frequency is
// not finite and > 0, or the model is singular.
FrfData synthesize_frf(const PlantModel& plant, double speed_rpm, const std::vector<double>& freq_hz,
                       const FrfSynthesisOptions& options = {});

// Evenly spaced grid fmin, fmin + df, ... <= fmax (+ half a step of slack).
std::vector<double> frequency_grid(double fmin_hz, double fmax_hz, double df_hz);

}  // namespace ambdiag
