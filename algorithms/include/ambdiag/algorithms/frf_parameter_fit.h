// Fitting a few physical parameters of a plant model to a measured FRF
// matrix: parameter vector p -> modified model -> FRF -> weighted residual,
// minimised by Levenberg-Marquardt within bounds.
//
//   chi2(p) = sum_{entries e, lines l} |w_el (H_e(p; f_l) + o_el - Hm_el)|^2
//
// with w = 1 / sigma (sigma: standard deviation of the complex residual, so
// E chi2 = number of complex values when the model is right) and o an
// optional offset added to every prediction (e.g. the healthy machine's
// measured-minus-model bias, so that only the change is modelled).
// Jacobian by forward differences (one model evaluation per parameter), or,
// with `broyden`, from a given start Jacobian (or differences once) updated
// by Broyden's rank-one secant formula after every evaluation, so that an
// iteration costs one model evaluation (for one parameter this is the
// secant method on the residual vector, superlinear near the solution).
// Steps are clamped into the bounds. The covariance of the estimate is the
// inverse Gauss-Newton Hessian (J^T J)^-1 / 2 of the real residual vector
// (each real part has variance 1/2), inflated by chi2 / dof when that
// exceeds 1 (misfit widens the interval).
#pragma once

#include <complex>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ambdiag/core/frf_data.h"

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

using FrfModelFunction = std::function<std::vector<std::vector<std::complex<double>>>(const Eigen::VectorXd&)>;

struct ParameterFitOptions {
  Eigen::VectorXd start, lower, upper;  // all the same size
  Eigen::VectorXd fd_step;              // absolute finite-difference steps; empty: 1e-4 * (upper - lower)
  int max_iterations = 30;
  double rel_tolerance = 1e-6;          // stop when chi2 falls by less than this fraction
  double step_tolerance = 1e-6;         // or when every step is below this fraction of (upper - lower)
  bool broyden = false;                 // secant updates instead of a difference Jacobian per iteration
  Eigen::MatrixXd jacobian0;            // d(real residual)/dp at start (2 x values rows); empty: differences
  bool is_valid(std::string* error) const;
};

struct ParameterFitResult {
  Eigen::VectorXd p;
  Eigen::MatrixXd covariance;  // of p; zeros for a parameter stuck at a bound with no curvature
  Eigen::MatrixXd jacobian;    // of the real residual at p (Broyden's estimate with `broyden`)
  double chi2 = 0.0;
  double chi2_start = 0.0;
  int evaluations = 0, iterations = 0;
  bool converged = false;
  std::string stop_reason;
};

// Weighted chi2 of a prediction against the target.
double fit_chi2(const FrfFitTarget& target, const std::vector<std::vector<std::complex<double>>>& model);

// Throws InputError on invalid options; not converging is reported.
ParameterFitResult fit_parameters(const FrfModelFunction& model, const FrfFitTarget& target,
                                  const ParameterFitOptions& options);

}  // namespace ambdiag
