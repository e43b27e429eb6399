// Shared by the real-data fit tests: every evident resonance peak of the
// measured |H| (found from the FRF itself, not from a fit) must be
// identified as a mode.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "ambdiag/algorithms/estimation/frf_estimation.h"
#include "ambdiag/algorithms/identification/rational_fit.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/run_recording.h"
#include "test_support.h"

namespace ambdiag::real_data {

// Evident peaks of S = sum_e |H_e|^2: the largest value within +-3 % of its
// frequency and at least 3 x the median of S over [0.8 f, 1.25 f] (5 dB;
// noise bumps of the estimated FRF stay below 1.3 x), away from the band
// edges.
inline std::vector<double> evident_peaks(const FrfData& frf) {
  const size_t n = frf.freq_hz.size();
  std::vector<double> s(n, 0.0);
  for (const auto& e : frf.entries)
    for (size_t l = 0; l < n; ++l) s[l] += std::norm(e.h[l]);
  std::vector<double> peaks;
  const double f_lo = 1.25 * frf.freq_hz.front() + 2.0 * (frf.freq_hz[1] - frf.freq_hz[0]), f_hi = 0.95 * frf.freq_hz.back();
  for (size_t l = 0; l < n; ++l) {
    const double f = frf.freq_hz[l];
    if (f < f_lo || f > f_hi) continue;
    bool top = true;
    std::vector<double> around;
    for (size_t k = 0; k < n; ++k) {
      const double fk = frf.freq_hz[k];
      if (std::abs(fk - f) <= 0.03 * f && s[k] > s[l]) top = false;
      if (fk >= 0.8 * f && fk <= 1.25 * f) around.push_back(s[k]);
    }
    if (!top) continue;
    std::nth_element(around.begin(), around.begin() + static_cast<long>(around.size() / 2), around.end());
    if (s[l] >= 3.0 * around[around.size() / 2]) peaks.push_back(f);
  }
  return peaks;
}

inline void expect_peaks_identified(const FrfData& frf, const RationalFitResult& fit, size_t min_peaks) {
  const std::vector<double> peaks = evident_peaks(frf);
  EXPECT_GE(peaks.size(), min_peaks);
  for (double f : peaks) {
    // A resonance peak of |H| lies inside the half-power band (+-zeta f) of
    // its mode, shifted by overlapping neighbours; 2 % and a line on top.
    const IdentifiedMode* near = nullptr;
    for (const auto& m : fit.modes)
      if (!near || std::abs(m.f_hz - f) < std::abs(near->f_hz - f)) near = &m;
    ASSERT_NE(near, nullptr);
    std::printf("peak %.2f Hz: nearest mode %.2f Hz (zeta %.4f)\n", f, near->f_hz, near->zeta);
    EXPECT_LE(std::abs(near->f_hz - f), (0.02 + near->zeta) * near->f_hz + (frf.freq_hz[1] - frf.freq_hz[0]))
        << "evident peak at " << f << " Hz";
  }
  for (const auto& m : fit.modes) std::printf("mode %.2f Hz zeta %.4f snr %.0f orders %d\n", m.f_hz, m.zeta, m.peak_snr, m.stable_orders);
}

}  // namespace ambdiag::real_data
