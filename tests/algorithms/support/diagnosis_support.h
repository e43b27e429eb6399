// Simulated measurements for the diagnosis tests: the plant model's FRF on
// the reference grid plus complex Gaussian noise with the references'
// sigma (re and im each sigma / sqrt(2)), seeded.
#pragma once

#include <cmath>
#include <complex>
#include <random>
#include <string>
#include <vector>

#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"
#include "test_support.h"

namespace ambdiag::testing {

inline PlantModel reference_plant() { return read_plant_file(data_file("reference_pump/plant.json").string()); }

inline std::vector<FrfData> reference_runs(int skip = 0) {
  std::vector<FrfData> v;
  for (int i = 1; i <= 5; ++i)
    if (i != skip) v.push_back(read_frf_csv(data_file("reference_pump/frf_ref_" + std::to_string(i) + ".csv").string()));
  return v;
}

// `clean` with noise of `like`'s sigma columns (which it also gets).
inline FrfData with_noise(const FrfData& clean, const FrfData& like, std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  FrfData out = clean;
  for (auto& e : out.entries) {
    const FrfEntry* s = like.find(e.output, e.input);
    e.sigma = s->sigma;
    for (size_t l = 0; l < e.h.size(); ++l) e.h[l] += e.sigma[l] / std::sqrt(2.0) * std::complex<double>(n(rng), n(rng));
  }
  return out;
}

}  // namespace ambdiag::testing
