// The one fitting mechanism of the algorithms: bounded Levenberg-Marquardt
// on a weighted complex residual r(x), minimising
//
//   chi2(x) = sum_k |r_k(x)|^2,   lower <= x <= upper,
//
// where r_k = (model_k(x) - measured_k) / sigma_k (plus whatever offset the
// caller folds in), so that chi2 has expectation (number of complex values)
// when the model is right and the noise is complex Gaussian with standard
// deviation sigma. Explain fits plant parameters through it
// (model/plant_frf_fit.h); the diagnosis fits fault and nuisance parameters
// through it (diagnosis/src/frf_fit_target.h).
//
// The Jacobian of the real residual vector (re, im of every r_k) is taken by
// forward differences at every iteration, or, with `broyden`, from a given
// start (or differences once) and updated by Broyden's rank-one secant
// formula after every evaluation, so that an iteration costs about one
// evaluation (for one parameter this is the secant method on the residual
// vector, superlinear near the solution). The step is solved in scaled
// coordinates u = x / scale with Marquardt's damping lambda diag(J^T J),
// then clamped into the bounds.
//
// Covariance of the estimate: (J^T J)^-1 times
//   - known noise (the weights are 1 / sigma of the complex values, so each
//     real component has variance 1/2): 1/2 max(1, chi2 / dof), misfit
//     widening the interval;
//   - estimated noise (the weights are only relative): chi2 / dof of the real
//     components, the classical least-squares estimate.
#pragma once

#include <complex>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace ambdiag {

// One fitted parameter, clamped to [lower, upper].
struct FitParameter {
  std::string name;
  double initial = 0.0;
  double lower = 0.0, upper = 0.0;
  double scale = 1.0;  // typical size of a change: the coordinate the step is solved in, and the difference step's unit
};

// How lambda moves: down after an accepted step, up after a rejected one.
// The defaults suit fits of many cheap evaluations (explain); the diagnosis,
// whose every evaluation is an FE solve, gives up sooner (frf_fit_target.h).
struct DampingSchedule {
  double grow = 4.0;        // lambda *= grow after a step that does not lower chi2
  double shrink = 0.25;     // lambda *= shrink after one that does (not below 1e-9)
  double max_lambda = 1e10; // the iteration gives up once lambda reaches this
  int max_rejections = std::numeric_limits<int>::max();  // or after this many rejected steps in a row
};

enum class NoiseLevel {
  known,      // weights are 1 / sigma: covariance (J^T J)^-1 / 2, inflated by chi2 / dof > 1
  estimated,  // weights are relative: covariance (J^T J)^-1 chi2 / dof
};

struct LeastSquaresOptions {
  int max_iterations = 20;
  double rel_tolerance = 1e-4;   // stop when an accepted step lowers chi2 by less than this fraction
  double step_tolerance = 0.0;   // stop when every step is at most this fraction of (upper - lower); 0: when nothing moves
  double fd_step = 1e-4;         // forward-difference step in units of each parameter's scale
  bool broyden = false;          // secant updates instead of a difference Jacobian per iteration
  Eigen::MatrixXd jacobian0;     // d(real residual)/dx at the start, (2 x values) x parameters; empty: differences
  DampingSchedule damping;
  NoiseLevel noise = NoiseLevel::estimated;
};

struct LeastSquaresResult {
  std::vector<double> x;
  std::vector<double> sd;       // sqrt of the covariance's diagonal; NaN at a bound or without curvature
  Eigen::MatrixXd covariance;   // of x; zeros when J^T J is singular
  Eigen::MatrixXd jacobian;     // of the real residual, at the last differenced point (Broyden's estimate with `broyden`)
  double chi2 = 0.0;
  double chi2_start = 0.0;
  int iterations = 0;
  int evaluations = 0;
  bool converged = false;
  std::string stop_reason;
};

using ResidualFunction = std::function<std::vector<std::complex<double>>(const std::vector<double>& x)>;

// Minimises chi2 from the clamped initial values. An empty parameter list
// just evaluates chi2. Throws InputError on a parameter with lower > upper,
// a scale that is not positive, or a jacobian0 of the wrong shape; not
// converging is reported in the result.
LeastSquaresResult fit_least_squares(const ResidualFunction& residual, const std::vector<FitParameter>& params,
                                     const LeastSquaresOptions& options = {});

double chi2_of(const std::vector<std::complex<double>>& r);

}  // namespace ambdiag
