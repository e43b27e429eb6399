// Fitting a few plant parameters to a measured FRF matrix: parameter vector
// -> modified plant (+ an acquisition delay applied to every FRF) -> model
// FRF on the measured grid -> noise-weighted residual, minimised by
// Levenberg-Marquardt within bounds.
//
// The weighted residual of entry e at line l is r = (H_model - H_meas) / sigma,
// so chi2 = sum |r|^2 has expectation (number of lines x entries) when the
// model is right and the noise is complex Gaussian with std sigma
// (frf_compare.h). Entries without sigma get sigma = 1 % of their RMS.
//
// Speed: the lateral rotor FRF (the costly part, synthesize_frf with the
// modal Krylov method) is cached by the rotor's parameters; housings, the
// axial model and the delay are closed forms evaluated per call, so fitting
// them costs no FE solve.
#pragma once

#include <complex>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag {

// A plant model plus what the measurement chain adds to it.
struct PlantVariant {
  PlantModel plant;
  double delay_s = 0.0;  // H_measured = H_plant exp(-j w delay_s) on every entry
};

// Model FRF of variants on (a subset of) a measured file's lines, and their
// weighted residuals. Not thread-safe (it caches).
class PlantFrfEvaluator {
 public:
  // Throws InputError if the measurement names a sensor/actuator pair the
  // plant model lacks (checked at the first evaluation).
  explicit PlantFrfEvaluator(const FrfData& measured);

  const FrfData& measured() const { return measured_; }
  // Speed at which the model is evaluated: the file's speed_rpm, else the plant's.
  double speed_rpm(const PlantModel& plant) const;
  // sigma of entry e at line l (from the file, or 1 % of the entry's RMS).
  double sigma(std::size_t e, std::size_t l) const { return sigma_[e][l]; }

  // Model H of every measured entry (outer) at the given lines (inner).
  std::vector<std::vector<std::complex<double>>> model_h(const PlantVariant& v, const std::vector<int>& lines);
  // Weighted residual (H_model - H_meas) / sigma, entry-major, at the lines.
  std::vector<std::complex<double>> residual(const PlantVariant& v, const std::vector<int>& lines);
  // The model FRF on the whole measured grid, as an FrfData like the measurement.
  FrfData model_frf(const PlantVariant& v);

  int rotor_solves() const { return rotor_solves_; }
  // Identifies what the lateral rotor FRF depends on (shaft, disks, links,
  // damping, lateral points, speed): equal keys, equal rotor FRFs.
  std::string rotor_key(const PlantModel& plant) const;

 private:
  const std::vector<std::vector<std::complex<double>>>& lateral(const PlantModel& plant, const std::vector<int>& lines);

  FrfData measured_;
  std::vector<std::vector<double>> sigma_;
  std::map<std::string, std::vector<std::vector<std::complex<double>>>> cache_;
  int rotor_solves_ = 0;
};

// One fitted parameter. Values move in a scaled coordinate u = (x - x0) / scale
// and are clamped to [lower, upper].
struct FitParameter {
  std::string name;
  double initial = 0.0;
  double lower = 0.0, upper = 0.0;
  double scale = 1.0;  // typical size of a change
};

using VariantBuilder = std::function<PlantVariant(const std::vector<double>& x)>;

// (Not ParameterFitOptions / ParameterFitResult: frf_parameter_fit.h has
// those names in the same namespace, and two class definitions of one name
// break the one-definition rule: their implicit inline members clash at link
// time; ASan caught the wrong destructor freeing a stack address.)
struct PlantFitOptions {
  int max_iterations = 20;
  double rel_tolerance = 1e-4;  // stop when chi2 improves by less than this fraction
};

struct PlantFitResult {
  std::vector<double> x;
  std::vector<double> sd;  // from (J^T J)^-1 scaled by chi2/dof (NaN at a bound)
  double chi2 = 0.0;       // on the fit lines
  double chi2_start = 0.0;
  int iterations = 0;
  int evaluations = 0;
  bool converged = false;
  std::string stop_reason;
};

// Levenberg-Marquardt on the weighted residual at `lines`, Jacobian by
// forward differences in the scaled coordinates. An empty parameter list
// just evaluates chi2.
PlantFitResult fit_parameters(PlantFrfEvaluator& eval, const VariantBuilder& build,
                                  const std::vector<FitParameter>& params, const std::vector<int>& lines,
                                  const PlantFitOptions& options = {});

// The same Levenberg-Marquardt on any weighted complex residual r(x).
using ResidualFunction = std::function<std::vector<std::complex<double>>(const std::vector<double>& x)>;
PlantFitResult fit_least_squares(const ResidualFunction& residual, const std::vector<FitParameter>& params,
                                     const PlantFitOptions& options = {});

double chi2_of(const std::vector<std::complex<double>>& r);

}  // namespace ambdiag
