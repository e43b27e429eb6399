// Private to the diagnosis: what its fits minimise, and how they fit.
//
//   chi2(p) = sum_{entries e, lines l} |w_el (H_e(p; f_l) + o_el - Hm_el)|^2
//
// with w = 1 / sigma (sigma: standard deviation of the complex residual, so
// E chi2 = number of complex values when the model is right) and o an
// optional offset added to every prediction (e.g. the healthy machine's
// measured-minus-model bias, so that only the change is modelled). The fit
// itself is the algorithms' one Levenberg-Marquardt
// (numerics/least_squares.h), with the noise level known and Broyden
// updates: every model evaluation here is an FE solve.
#pragma once

#include <complex>
#include <functional>
#include <limits>
#include <vector>

#include "ambdiag/algorithms/numerics/least_squares.h"

namespace ambdiag {

// What is fitted: measured values, weights and offsets per entry and line.
// The model function must return, for a parameter vector, the FRF values of
// the same entries on the same lines (entry-major: [entry][line]).
struct FrfFitTarget {
  std::vector<double> freq_hz;
  std::vector<std::vector<std::complex<double>>> measured;  // [entry][line]
  std::vector<std::vector<double>> weight;                  // 1 / sigma, [entry][line]
  std::vector<std::vector<std::complex<double>>> offset;    // [entry][line]; empty: none
  int values() const;  // complex values (entries x lines)
};

using FrfModelFunction = std::function<std::vector<std::vector<std::complex<double>>>(const std::vector<double>& p)>;

// The weighted residual w (H + o - Hm), entry-major; logic_error when the
// model's shape is not the target's.
std::vector<std::complex<double>> fit_residual(const FrfFitTarget& target,
                                               const std::vector<std::vector<std::complex<double>>>& model);
// Weighted chi2 of a prediction against the target.
double fit_chi2(const FrfFitTarget& target, const std::vector<std::vector<std::complex<double>>>& model);

// The diagnosis's fitting options: known noise level, Broyden updates, and
// a damping schedule that gives up after 6 rejected steps (each costs a
// solve): lambda x10 up, x0.2 down.
LeastSquaresOptions secant_fit_options(int max_iterations, double rel_tolerance, double step_tolerance);

// fit_least_squares of the model's weighted residual against the target.
LeastSquaresResult fit_parameters(const FrfModelFunction& model, const FrfFitTarget& target,
                                  const std::vector<FitParameter>& params, const LeastSquaresOptions& options);

}  // namespace ambdiag
