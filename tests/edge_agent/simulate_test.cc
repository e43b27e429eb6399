// The closed-loop simulator's runs carry the plant's FRF: estimating the FRF
// back from a simulated run (the estimator `ambdiag frf` uses, references as
// instruments) gives the model's FRF, to float32 and anti-alias precision
// without noise and within the estimator's own sigma with noise; faults
// change it as their models say.
#include "ambdiag/edge_agent/simulate.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>

#include "ambdiag/algorithms/diagnosis/diagnosis.h"
#include "ambdiag/algorithms/diagnosis/fault_models.h"
#include "ambdiag/algorithms/diagnosis/reference_statistics.h"
#include "ambdiag/algorithms/estimation/frf_estimation.h"
#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/core/error.h"
#include "ambdiag/core/frf_data.h"
#include "simulate_support.h"
#include "test_support.h"

namespace ambdiag::agent {
namespace {

TEST(PumpSimulator, NoiseFreeClosedLoopRunCarriesTheModelFrf) {
  PumpSimulator sim(model_path(), small(false));
  const RunRecording run = sim.identification_run();
  EXPECT_EQ(run.pump_id, "SIM-1");
  EXPECT_EQ(run.channels.size(), 16u);  // 5 references, 5 forces, 5 displacements, speed
  const FrfEstimate est = estimate_frf(run);
  ASSERT_EQ(est.frf.entries.size(), 25u);
  // What is left: float32 samples (1e-7), the held current's images after
  // the anti-alias filter (< 1e-4 of the line) and the transient after a
  // settle period (e^-40). 4e-6 seen.
  EXPECT_LT(reported("nrmse noise free", nrmse(est.frf, model_frf(sim.plant(), est.frf))), 1e-4);
}

// |H_est - H_model|^2 / sigma^2 averages to 1 for an unbiased estimate with
// the true sigma. The estimator's sigma^2 comes from the period-to-period
// scatter, chi^2 with nu = 2 (complex) x segments x (periods - 1) degrees of
// freedom, so the mean of 1 / sigma_hat^2 is nu / (nu - 2) / sigma^2: 1.25
// for 5 segments of 2 measured periods. A closed-loop bias (regressing on
// the noisy forces) or a simulation that is not the model would add
// |bias|^2 / sigma^2. The residual unbalance is left out here: a 1x line
// that is not periodic in the multisine period inflates sigma (next tests).
TEST(PumpSimulator, NoisyClosedLoopRunAgreesWithTheModelWithinSigma) {
  SimulationOptions o = small(true);
  o.unbalance_grade_mm_per_s = 0;
  PumpSimulator sim(model_path(), o);
  const FrfEstimate est = estimate_frf(sim.identification_run());
  const FrfData model = model_frf(sim.plant(), est.frf);
  const double nu = 2.0 * 5 * (o.meas_periods - 1), expected = nu / (nu - 2);
  double sum = 0;
  long n = 0;
  for (const auto& e : est.frf.entries) {
    const FrfEntry* m = model.find(e.output, e.input);
    ASSERT_NE(m, nullptr);
    ASSERT_EQ(e.sigma.size(), e.h.size());
    for (size_t k = 0; k < e.h.size(); ++k) {
      if (!(e.sigma[k] > 0)) continue;
      sum += std::norm(e.h[k] - m->h[k]) / (e.sigma[k] * e.sigma[k]);
      ++n;
    }
  }
  ASSERT_GT(n, 1000);
  EXPECT_NEAR(reported("mean |dH|^2 / sigma^2", sum / static_cast<double>(n)), expected, 0.25 * expected);
}

TEST(PumpSimulator, StepsineRunCarriesTheModelFrf) {
  SimulationOptions o = small(false);
  o.excitation = "stepsine";
  o.sample_rate_hz = 8192;
  o.f_min_hz = 10;
  o.f_max_hz = 900;
  o.stepsine_steps = 6;
  o.stepsine_settle_s = 0.1;
  PumpSimulator sim(model_path(), o);
  const RunRecording run = sim.identification_run();
  ASSERT_TRUE(run.excitation);
  EXPECT_EQ(run.excitation->segments.size(), 5u * 6u);
  const FrfEstimate est = estimate_frf(run);
  EXPECT_EQ(est.method, "stepsine");
  EXPECT_LT(reported("nrmse stepsine", nrmse(est.frf, model_frf(sim.plant(), est.frf))), 5e-3);
}

// A channel fault scales its row (sensor) or column (actuator) of the FRF,
// although the controller closes the loop through the faulty channel.
TEST(PumpSimulator, SensorAndActuatorFaultsScaleTheirRowAndColumn) {
  SimulationOptions o = small(false);
  o.faults = {"sensor_fault=0.8", "actuator_fault"};
  PumpSimulator sim(model_path(), o);
  const FrfEstimate est = estimate_frf(sim.identification_run());
  FrfData expected = model_frf(sim.plant(), est.frf);
  for (auto& e : expected.entries)
    for (auto& h : e.h) h *= (e.output == "xAx" ? 0.8 : 1.0) * (e.input == "fAx" ? 0.7 : 1.0);
  EXPECT_LT(reported("nrmse vs scaled model", nrmse(est.frf, expected)), 1e-4);
  EXPECT_GT(nrmse(est.frf, model_frf(sim.plant(), est.frf)), 0.05);
}

// A plant fault by name: the run carries the faulty plant's FRF, not the
// healthy one.
TEST(PumpSimulator, DryRunChangesTheFrfToTheFaultyPlants) {
  SimulationOptions o = small(false);
  o.faults = {"dry_run"};
  PumpSimulator sim(model_path(), o);
  const FrfEstimate est = estimate_frf(sim.identification_run());
  const PlantModel healthy = read_plant_file(model_path());
  for (const auto& l : sim.plant().links) {
    if (l.kind == "seal" || l.kind == "balance_piston") {
      EXPECT_EQ(l.get(LinkCoef::kxx), 0.0) << l.name;
    }
  }
  EXPECT_LT(reported("nrmse vs dry-run model", nrmse(est.frf, model_frf(sim.plant(), est.frf))), 1e-4);
  EXPECT_GT(reported("nrmse vs healthy model", nrmse(est.frf, model_frf(healthy, est.frf))), 0.1);
}

// Unbalance is a forced 1x response: the 1x bearing forces grow with u (10x
// the residual), the 2x ones do not; the loop is linear so the ratio is 10.
TEST(PumpSimulator, UnbalanceRaisesThe1xBearingForcesTenfold) {
  SimulationOptions o = small(true);
  PumpSimulator healthy(model_path(), o);
  o.faults = {"unbalance"};
  PumpSimulator faulty(model_path(), o);
  healthy.monitoring_snapshot();  // let the start transient pass
  faulty.monitoring_snapshot();
  const Snapshot a = healthy.monitoring_snapshot(), b = faulty.monitoring_snapshot();
  for (size_t k = 0; k < 4; ++k) {
    EXPECT_GT(a.force_1x_amp_n[k], 0.1) << k;
    EXPECT_NEAR(reported("1x force ratio", b.force_1x_amp_n[k] / a.force_1x_amp_n[k]), 10.0, 0.5) << k;
    EXPECT_LT(b.force_2x_amp_n[k], 0.05 * b.force_1x_amp_n[k]) << k;
  }
  for (size_t p = 0; p < 2; ++p) {
    EXPECT_NEAR(b.orbit_major_m[p] / a.orbit_major_m[p], 10.0, 1.5) << p;
    EXPECT_LE(b.orbit_minor_m[p], b.orbit_major_m[p]);
  }
}

// A pump at 3000.4 rpm on 2 Hz lines: 1x (50.007 Hz) is nearly periodic with
// the excitation. The line it falls on is dropped, and the large unbalance
// response (10 x the residual) must not leak into the lines around it: there
// |H - model|^2 / sigma^2 stays at the estimator's noise level (nu / (nu - 2))
// as on the rest of the band. Before the near-grid harmonic was fitted, the
// 1 Hz pumps of the demo at 2998 and 3001 rpm showed 40-2000 on the lines
// 41-56 Hz and a false detection.
TEST(PumpSimulator, NearGridUnbalanceLeavesTheLinesAroundItToTheNoise) {
  SimulationOptions o = small(true);
  o.faults = {"unbalance"};
  PlantModel plant = read_plant_file(model_path());
  plant.speed_rpm = 3000.4;
  PumpSimulator sim(plant, o);
  const FrfEstimate est = estimate_frf(sim.identification_run());
  const auto dropped = std::find_if(est.warnings.begin(), est.warnings.end(), [](const std::string& w) {
    return w.find("1x the speed") != std::string::npos && w.find("50 Hz") != std::string::npos;
  });
  EXPECT_NE(dropped, est.warnings.end()) << "the 50 Hz line should be dropped";
  EXPECT_EQ(std::count(est.frf.freq_hz.begin(), est.frf.freq_hz.end(), 50.0), 0);
  const FrfData model = model_frf(sim.plant(), est.frf);
  const double nu = 2.0 * 5 * (o.meas_periods - 1), expected = nu / (nu - 2);
  double near = 0, worst = 0;
  long n = 0;
  for (const auto& e : est.frf.entries) {
    const FrfEntry* m = model.find(e.output, e.input);
    ASSERT_NE(m, nullptr);
    for (size_t k = 0; k < e.h.size(); ++k) {
      if (std::abs(est.frf.freq_hz[k] - 50.0) > 10.0 || !(e.sigma[k] > 0)) continue;
      const double z = std::norm(e.h[k] - m->h[k]) / (e.sigma[k] * e.sigma[k]);
      near += z;
      worst = std::max(worst, z);
      ++n;
    }
  }
  ASSERT_GT(n, 200);  // 10 lines x 25 entries
  // 250 terms of mean `expected`: 3 standard errors of an F(2, nu) mean are
  // about 0.35 x expected; a leak of a tenth of the unbalance line is 100s.
  EXPECT_NEAR(reported("mean |dH|^2 / sigma^2 within 10 Hz of 1x", near / static_cast<double>(n)), expected, 0.35 * expected);
  EXPECT_LT(reported("worst |dH|^2 / sigma^2 there", worst), 100.0);  // F(2, 10) > 50: 6e-6 a term
}

// The whole chain on a healthy machine: a default identification run of
// the simulated reference pump (1 Hz lines to 1 kHz, 4 measured periods per
// segment), `ambdiag frf`'s estimator, and detection against the shared
// references (independent generator): no alarm at alpha = 1 %. The sigma
// of such a run rests on about 30 degrees of freedom, which the detection
// takes from the FRF's `sigma_dof`.
TEST(PumpSimulator, HealthyRunIsNotDetectedAgainstTheSharedReferences) {
  SimulationOptions o;
  o.pump_id = "SIM-1";
  PumpSimulator sim(model_path(), o);
  const FrfEstimate est = estimate_frf(sim.identification_run());
  ASSERT_TRUE(est.frf.meta("sigma_dof"));
  std::vector<FrfData> refs;
  for (int i = 1; i <= 5; ++i)
    refs.push_back(read_frf_csv(ambdiag::testing::data_file("reference_pump/frf_ref_" + std::to_string(i) + ".csv").string()));
  DiagnosisOptions opt;
  opt.detect_only = true;
  const DiagnosisResult r = diagnose(sim.plant(), reference_statistics(refs), est.frf, opt);
  reported("sigma_dof", std::stod(*est.frf.meta("sigma_dof")));
  reported("statistic / threshold", r.statistic / r.threshold);
  reported("p", r.p_value);
  EXPECT_FALSE(r.detected) << "T = " << r.statistic << ", threshold " << r.threshold;
}

TEST(PumpSimulator, RefusesUnknownFaultsAndBadValues) {
  SimulationOptions o = small(false);
  o.faults = {"bearing_fire"};
  EXPECT_THROW(PumpSimulator(model_path(), o), InputError);
  o.faults = {"dry_run=2"};  // fluid_factor in [0, 1]
  EXPECT_THROW(PumpSimulator(model_path(), o), InputError);
  o.faults = {"sensor_fault=abc"};
  EXPECT_THROW(PumpSimulator(model_path(), o), InputError);
}

}  // namespace
}  // namespace ambdiag::agent
