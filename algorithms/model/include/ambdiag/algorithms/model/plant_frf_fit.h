// Fitting a few plant parameters to a measured FRF matrix: parameter vector
// -> modified plant (+ an acquisition delay applied to every FRF) -> model
// FRF on the measured grid -> noise-weighted residual, minimised by
// Levenberg-Marquardt within bounds (numerics/least_squares.h).
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

#include "ambdiag/algorithms/numerics/least_squares.h"
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

using VariantBuilder = std::function<PlantVariant(const std::vector<double>& x)>;

// Fits the parameters x of build(x) to the weighted residual at `lines`
// (numerics/least_squares.h, estimated noise level by default: explain's
// weights come from sigma, but its model is known to be incomplete).
LeastSquaresResult fit_parameters(PlantFrfEvaluator& eval, const VariantBuilder& build,
                                  const std::vector<FitParameter>& params, const std::vector<int>& lines,
                                  const LeastSquaresOptions& options = {});

}  // namespace ambdiag
