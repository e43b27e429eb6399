// Test helpers for explain: a "recording" made by our own simulator, the
// model FRF plus complex Gaussian noise like the shared files (sigma = 1 %
// of each entry's RMS; entries that are zero get 1e-3 of the largest RMS).
#pragma once

#include <cmath>
#include <random>

#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/algorithms/model/plant_frf_fit.h"

namespace ambdiag::testing {

// Adds the recording's noise to a clean FRF (and the acquisition delay:
// h -> h exp(-j w delay_s) + noise), sigma columns set.
inline void add_recording_noise(FrfData& f, double delay_s, unsigned seed, double noise_rel = 0.01) {
  double max_rms = 0.0;
  std::vector<double> rms;
  for (const auto& e : f.entries) {
    double s = 0.0;
    for (const auto& h : e.h) s += std::norm(h);
    rms.push_back(std::sqrt(s / static_cast<double>(e.h.size())));
    max_rms = std::max(max_rms, rms.back());
  }
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (size_t k = 0; k < f.entries.size(); ++k) {
    auto& e = f.entries[k];
    const double sigma = noise_rel * (rms[k] > 1e-6 * max_rms ? rms[k] : 1e-3 * max_rms);
    e.sigma.assign(e.h.size(), sigma);
    for (size_t l = 0; l < e.h.size(); ++l) {
      const double w = 2 * M_PI * f.freq_hz[l];
      e.h[l] = e.h[l] * std::polar(1.0, -w * delay_s) + sigma / std::sqrt(2.0) * std::complex<double>(n01(rng), n01(rng));
    }
  }
}

inline FrfData noisy_recording(const PlantVariant& truth, const std::vector<double>& freq_hz, unsigned seed,
                               double noise_rel = 0.01) {
  FrfData f = synthesize_frf(truth.plant, truth.plant.speed_rpm, freq_hz, {FrfMethod::modal});
  f.speed_rpm = truth.plant.speed_rpm;
  add_recording_noise(f, truth.delay_s, seed, noise_rel);
  return f;
}

}  // namespace ambdiag::testing
