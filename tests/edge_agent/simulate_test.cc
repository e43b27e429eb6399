// The simulator's runs carry the model's FRF: estimating the FRF back from a
// simulated run (the same estimator `ambdiag frf` uses) must give the
// synthesised FRF, exactly without noise, within the noise with it.
#include "ambdiag/edge_agent/simulate.h"

#include <gtest/gtest.h>

#include <cmath>

#include "ambdiag/algorithms/frf_estimation.h"
#include "ambdiag/algorithms/frf_synthesis.h"
#include "ambdiag/core/error.h"
#include "test_support.h"

namespace ambdiag::agent {
namespace {

// rms |H_est - H_model| / rms |H_model| over every entry and line.
double nrmse(const FrfData& est, const PlantModel& plant) {
  const FrfData model = synthesize_frf(plant, plant.speed_rpm, est.freq_hz);
  double num = 0, den = 0;
  for (const auto& e : est.entries) {
    const FrfEntry* m = model.find(e.output, e.input);
    EXPECT_NE(m, nullptr) << e.output << "/" << e.input;
    if (!m) continue;
    for (size_t k = 0; k < e.h.size(); ++k) {
      num += std::norm(e.h[k] - m->h[k]);
      den += std::norm(m->h[k]);
    }
  }
  return std::sqrt(num / den);
}

SimulationOptions small(double noise) {
  SimulationOptions o;
  o.pump_id = "SIM-1";
  o.sample_rate_hz = 2048;
  o.period_samples = 1024;  // 2 Hz lines
  o.f_min_hz = 10;
  o.f_max_hz = 400;
  o.noise_fraction = noise;
  return o;
}

TEST(PumpSimulator, RunWithoutNoiseCarriesTheModelFrf) {
  const std::string model = ambdiag::testing::data_file("reference_pump/plant.json").string();
  PumpSimulator sim(model, small(0.0));
  const RunRecording run = sim.identification_run();
  EXPECT_EQ(run.pump_id, "SIM-1");
  const FrfEstimate est = estimate_frf(run);
  ASSERT_FALSE(est.frf.entries.empty());
  // float32 samples: about 1e-7 relative per sample.
  EXPECT_LT(nrmse(est.frf, read_plant_file(model)), 1e-4);
}

TEST(PumpSimulator, NoisyRunCarriesTheModelFrfWithinTheNoise) {
  const std::string model = ambdiag::testing::data_file("reference_pump/plant.json").string();
  PumpSimulator sim(model, small(0.01));
  const FrfEstimate est = estimate_frf(sim.identification_run());
  const double e = nrmse(est.frf, read_plant_file(model));
  EXPECT_GT(e, 1e-5);  // the noise is there
  EXPECT_LT(e, 0.1);
}

TEST(PumpSimulator, RefusesFaultsItCannotInject) {
  const std::string model = ambdiag::testing::data_file("reference_pump/plant.json").string();
  SimulationOptions o = small(0.0);
  o.faults = {"rotor_crack"};
  EXPECT_THROW(PumpSimulator(model, o), InputError);
}

}  // namespace
}  // namespace ambdiag::agent
