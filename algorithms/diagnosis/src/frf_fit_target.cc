#include "frf_fit_target.h"

#include <stdexcept>

namespace ambdiag {

int FrfFitTarget::values() const {
  int n = 0;
  for (const auto& e : measured) n += static_cast<int>(e.size());
  return n;
}

std::vector<std::complex<double>> fit_residual(const FrfFitTarget& t, const std::vector<std::vector<std::complex<double>>>& model) {
  if (model.size() != t.measured.size()) throw std::logic_error("diagnosis fit: model returned the wrong number of entries");
  std::vector<std::complex<double>> r;
  r.reserve(static_cast<size_t>(t.values()));
  for (size_t e = 0; e < t.measured.size(); ++e) {
    if (model[e].size() != t.measured[e].size()) throw std::logic_error("diagnosis fit: model returned the wrong number of lines");
    for (size_t l = 0; l < t.measured[e].size(); ++l) {
      std::complex<double> d = model[e][l] - t.measured[e][l];
      if (!t.offset.empty()) d += t.offset[e][l];
      r.push_back(d * t.weight[e][l]);
    }
  }
  return r;
}

double fit_chi2(const FrfFitTarget& target, const std::vector<std::vector<std::complex<double>>>& model) {
  return chi2_of(fit_residual(target, model));
}

LeastSquaresOptions secant_fit_options(int max_iterations, double rel_tolerance, double step_tolerance) {
  LeastSquaresOptions o;
  o.max_iterations = max_iterations;
  o.rel_tolerance = rel_tolerance;
  o.step_tolerance = step_tolerance;
  o.broyden = true;
  o.noise = NoiseLevel::known;
  o.damping.grow = 10.0;
  o.damping.shrink = 0.2;
  o.damping.max_lambda = std::numeric_limits<double>::infinity();
  o.damping.max_rejections = 6;
  return o;
}

LeastSquaresResult fit_parameters(const FrfModelFunction& model, const FrfFitTarget& target,
                                  const std::vector<FitParameter>& params, const LeastSquaresOptions& options) {
  return fit_least_squares([&](const std::vector<double>& p) { return fit_residual(target, model(p)); }, params, options);
}

}  // namespace ambdiag
