// Shared by the simulator's tests: the shared pump's model file, short run
// options, the model's FRF on an estimate's grid, the NRMSE between two FRF
// matrices, and a value printed into the test log.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <string>

#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/edge_agent/simulate.h"
#include "test_support.h"

namespace ambdiag::agent {

inline std::string model_path() { return ambdiag::testing::data_file("reference_pump/plant.json").string(); }

// Short runs: 2 Hz lines up to 600 Hz; with noise 2 settle + 2 measured
// periods (0.5 s each), without 1 + 1 (the slowest closed-loop pole of the
// reference pump decays in 12 ms).
inline SimulationOptions small(bool noise) {
  SimulationOptions o;
  o.pump_id = "SIM-1";
  o.sample_rate_hz = 2048;
  o.period_samples = 1024;
  o.f_min_hz = 2;
  o.f_max_hz = 600;
  o.meas_periods = 2;
  if (!noise) {
    o.settle_periods = 1;
    o.meas_periods = 1;
    o.loop.displacement_noise_m = 0;
    o.loop.current_noise_a = 0;
    o.unbalance_grade_mm_per_s = 0;
  }
  return o;
}

// Prints "[ value    ] what = v" (the figure a test checked) and returns v.
inline double reported(const char* what, double v) {
  std::cout << "[ value    ] " << what << " = " << v << "\n";
  return v;
}

// rms |H_a - H_b| / rms |H_b| over every entry and line.
inline double nrmse(const FrfData& a, const FrfData& b) {
  double num = 0, den = 0;
  for (const auto& e : a.entries) {
    const FrfEntry* m = b.find(e.output, e.input);
    EXPECT_NE(m, nullptr) << e.output << "/" << e.input;
    if (!m) continue;
    for (size_t k = 0; k < e.h.size(); ++k) num += std::norm(e.h[k] - m->h[k]), den += std::norm(m->h[k]);
  }
  return std::sqrt(num / den);
}

// The plant's FRF at its own speed on the grid of `at`.
inline FrfData model_frf(const PlantModel& plant, const FrfData& at) {
  return synthesize_frf(plant, plant.speed_rpm, at.freq_hz);
}

}  // namespace ambdiag::agent
