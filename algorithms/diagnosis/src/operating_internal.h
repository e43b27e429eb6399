// Private to the operating reference: the nuisance (log factors on the
// fluid-seal links) and its fit to one run (operating_reference.h).
#pragma once

#include <complex>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ambdiag/algorithms/diagnosis/operating_reference.h"
#include "diagnosis_internal.h"

namespace ambdiag::operating_detail {

using Values = std::vector<std::vector<std::complex<double>>>;  // [entry][line]

// The plant with link links[k]'s coefficients (and speed table) times exp(theta[k]).
PlantModel with_nuisance(const PlantModel& plant, const std::vector<int>& links, const Eigen::VectorXd& theta);

// Model FRF values of `plant` on the skeleton's grid, entries and speed,
// with the diagnosis' synthesis (modal, Krylov basis, banded damping).
Values model_values(const PlantModel& plant, const FrfData& skeleton);

// What is fitted: measured H, weights 1 / sqrt(var), offset b, per entry.
struct RunData {
  FrfData skeleton;  // grid, speed, entry names
  Values h, offset;
  std::vector<std::vector<double>> weight;
};

struct NuisanceFit {
  Eigen::VectorXd theta;        // fitted log factors
  Eigen::MatrixXd cov;          // of theta (noise)
  double chi2 = 0.0;            // sum |w (M(theta) + b - H)|^2
  Values at_theta;              // M(s, theta)
  Values at_start;              // M(s, start)
  std::vector<Values> jacobian; // dM/dtheta_k at start, FRF units, [k][entry][line]
  int evaluations = 0;
};

// Levenberg-Marquardt with Broyden updates from a difference Jacobian at
// `start` (1 + K + iterations model FRFs). With no links, theta is empty
// and chi2 that of M(s, 0). An empty run.offset is zero.
NuisanceFit fit_nuisance(const PlantModel& plant, const std::vector<int>& links, const RunData& run, double bound,
                         const Eigen::VectorXd& start);

// The normal spread of theta for a new run: (1 + 1/n) Sigma (the run's own
// drift and that of the references' mean) plus the mean's noise, plus
// `estimate_cov` (the run's fit) when given.
Eigen::MatrixXd drift_covariance(const OperatingReference& ref, const Eigen::MatrixXd& estimate_cov);

// The ranked fault diagnosis of a detected run (a: aligned with mean = the
// drift-fitted prediction; res: its detection filled in, residual test's
// threshold in res.threshold). Fills faults, explained, chi2 and NRMSE
// before / after, the models; returns the model FRFs spent.
int diagnose_faults(const PlantModel& plant, const std::vector<int>& links, const OperatingReference& ref,
                    const diagnosis_detail::Aligned& a, const RunData& run, const NuisanceFit& nf, const DiagnosisOptions& options,
                    DiagnosisResult& res);

}  // namespace ambdiag::operating_detail
