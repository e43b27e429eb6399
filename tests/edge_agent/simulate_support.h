// Shared by the simulator's tests: the shared pump's model file, the model's
// FRF on an estimate's grid, and the NRMSE between two FRF matrices.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "ambdiag/algorithms/frf_synthesis.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"
#include "test_support.h"

namespace ambdiag::agent {

inline std::string model_path() { return ambdiag::testing::data_file("reference_pump/plant.json").string(); }

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
