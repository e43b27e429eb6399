// Detection and diagnosis on the shared data (independent generator) and on
// faults simulated by the fault models plus noise.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>

#include "ambdiag/algorithms/diagnosis/diagnosis.h"
#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/algorithms/numerics/chi_square.h"
#include "ambdiag/core/error.h"
#include "diagnosis_support.h"
#include "test_support.h"

namespace ambdiag {
namespace {

using testing::data_file;
using testing::reference_plant;
using testing::reference_runs;

FrfData case_frf(const std::string& c) { return read_frf_csv(data_file(c + "/frf.csv").string()); }

const ReferenceStatistics& shared_reference() {
  static const ReferenceStatistics r = reference_statistics(reference_runs());
  return r;
}

const FaultHypothesis* find_hyp(const std::vector<FaultHypothesis>& hs, FaultKind k, int element = -1, const std::string& ch = "") {
  for (const auto& h : hs)
    if (h.kind == k && (element < 0 || (h.elements.size() == 1 && h.elements[0] == element)) && (ch.empty() || h.channel == ch)) return &h;
  return nullptr;
}

// The five healthy runs scatter as their sigma columns say (1 % noise):
// the pooled between-run statistic is chi2 with 8 x 1000 dof per entry,
// so its ratio to the dof is 1 within 3 x sqrt(2 / 8000) = 0.05.
TEST(ReferenceStatistics, SharedRunsScatterAsTheirSigmaSays) {
  const ReferenceStatistics& r = shared_reference();
  EXPECT_EQ(r.runs, 5);
  ASSERT_EQ(r.entries.size(), 25u);
  for (const auto& e : r.entries) {
    EXPECT_NEAR(e.scatter_ratio, 1.0, 0.05) << e.output << "/" << e.input;
    EXPECT_TRUE(e.sigma_stated);
  }
}

// Runs whose scatter exceeds their stated sigma (e.g. run-to-run changes
// the sigma columns do not know about) get their variance scaled up.
TEST(ReferenceStatistics, ScatterAboveSigmaScalesTheVariance) {
  std::vector<FrfData> runs = reference_runs();
  for (auto& run : runs)
    for (auto& e : run.entries)
      for (auto& s : e.sigma) s *= 0.5;  // stated noise too small by 2: variance by 4
  const ReferenceStatistics r = reference_statistics(runs);
  for (const auto& e : r.entries) EXPECT_NEAR(e.kappa, 4.0, 0.25);
}

TEST(ReferenceStatistics, RefusesRunsOnDifferentGridsOrSpeeds) {
  std::vector<FrfData> runs = reference_runs();
  runs[2].freq_hz[10] += 0.25;
  EXPECT_THROW(reference_statistics(runs), InputError);
  runs = reference_runs();
  runs[1].speed_rpm = 2000.0;
  EXPECT_THROW(reference_statistics(runs), InputError);
  EXPECT_THROW(reference_statistics({}), InputError);
}

// Each healthy run against the statistics of the other four: no detection.
TEST(Diagnosis, ReferenceRunsAreNotDetected) {
  const PlantModel plant = reference_plant();
  for (int i = 1; i <= 5; ++i) {
    const ReferenceStatistics ref = reference_statistics(reference_runs(i));
    const FrfData meas = read_frf_csv(data_file("reference_pump/frf_ref_" + std::to_string(i) + ".csv").string());
    const DiagnosisResult r = diagnose(plant, ref, meas);
    EXPECT_FALSE(r.detected) << "frf_ref_" << i << ": statistic " << r.statistic << " threshold " << r.threshold;
    EXPECT_LT(r.statistic / r.dof, 1.02);
    EXPECT_TRUE(r.faults.empty());
  }
}

// The false-alarm rate is what alpha says: 200 healthy measurements, the
// model FRF (which sits at the noise floor of the shared runs) plus noise
// with the references' sigma, against the shared references. Detections
// are binomial(200, 0.05): mean 10, sd 3.1. (diagnosis_slow_test: 1000
// machines with fresh references each, at alpha 0.01 and 0.05.)
TEST(Diagnosis, FalseAlarmRateMatchesAlpha) {
  const PlantModel plant = reference_plant();
  const FrfData like = read_frf_csv(data_file("reference_pump/frf_ref_1.csv").string());
  const FrfData clean = model_frf_like(plant, like);
  std::mt19937_64 rng(20240601);
  DiagnosisOptions opt;
  opt.alpha = 0.05;
  opt.detect_only = true;
  int alarms = 0;
  const int n = 200;
  for (int k = 0; k < n; ++k) alarms += diagnose(plant, shared_reference(), testing::with_noise(clean, like, rng), opt).detected;
  RecordProperty("alarms_of_200_at_alpha_0.05", alarms);
  EXPECT_GE(alarms, 3);
  EXPECT_LE(alarms, 19);
}

// A measured sigma rests on few periods: sigma_hat^2 = sigma^2 chi2_nu / nu
// per line, independent of the noise on H. Each term of T then has the
// mean 2 nu / (nu - 2) instead of 2 (7 % more at nu = 30), and a healthy
// machine would alarm every time at 25,000 values; with the file's
// `sigma_dof` the test keeps its false-alarm rate.
TEST(Diagnosis, EstimatedSigmaWithItsDegreesOfFreedomKeepsTheFalseAlarmRate) {
  const PlantModel plant = reference_plant();
  const FrfData like = read_frf_csv(data_file("reference_pump/frf_ref_1.csv").string());
  const FrfData clean = model_frf_like(plant, like);
  const int nu = 30;
  std::mt19937_64 rng(20261122);
  std::chi_squared_distribution<double> chi2(nu);
  auto measured = [&]() {
    FrfData m = testing::with_noise(clean, like, rng);
    for (auto& e : m.entries)
      for (double& s : e.sigma) s *= std::sqrt(chi2(rng) / nu);
    return m;
  };
  DiagnosisOptions opt;
  opt.alpha = 0.05;
  opt.detect_only = true;
  int unaware = 0;
  for (int k = 0; k < 10; ++k) unaware += diagnose(plant, shared_reference(), measured(), opt).detected;
  EXPECT_GE(unaware, 9) << "without sigma_dof the bias should alarm";
  int alarms = 0;
  const int n = 200;
  for (int k = 0; k < n; ++k) {
    FrfData m = measured();
    m.set_meta("sigma_dof", std::to_string(nu));
    const DiagnosisResult r = diagnose(plant, shared_reference(), m, opt);
    alarms += r.detected;
    if (k == 0) {
      EXPECT_LT(r.dof, 2.0 * 25 * 1000);  // heavier tails than chi2_50000
      EXPECT_GT(r.threshold, chi2_quantile(0.95, 2.0 * 25 * 1000));
    }
  }
  RecordProperty("alarms_of_200_at_alpha_0.05_nu_30", alarms);
  // Binomial(200, 0.05): mean 10, sd 3.1.
  EXPECT_GE(alarms, 3);
  EXPECT_LE(alarms, 19);
}

TEST(Diagnosis, RefusesTooFewOrUnreadableSigmaDegreesOfFreedom) {
  const PlantModel plant = reference_plant();
  FrfData m = read_frf_csv(data_file("reference_pump/frf_ref_1.csv").string());
  DiagnosisOptions opt;
  opt.detect_only = true;
  for (const char* bad : {"4", "two", "nan", "-3"}) {
    m.set_meta("sigma_dof", bad);
    try {
      diagnose(plant, shared_reference(), m, opt);
      ADD_FAILURE() << "sigma_dof " << bad << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("sigma_dof"), std::string::npos) << e.what();
    }
  }
}

// The paper's case: no water in the pump. Detected, dry run first, the
// fluid forces gone (factor near 0), and the simulated faulty FRF agrees
// with the measured one (NRMSE falls to the noise level, ~1 %).
TEST(Diagnosis, DryRunIsDetectedAndRankedFirst) {
  const FrfData meas = case_frf("fault_dry_run");
  const DiagnosisResult r = diagnose(reference_plant(), shared_reference(), meas);
  ASSERT_TRUE(r.detected);
  EXPECT_GT(r.statistic, 10 * r.threshold);
  ASSERT_FALSE(r.faults.empty());
  EXPECT_EQ(r.faults.front().name, "dry_run");
  EXPECT_LT(r.faults.front().value, 0.1);
  EXPECT_TRUE(r.explained);
  EXPECT_EQ(r.isolation, "multiplicative");
  EXPECT_GT(r.nrmse_before, 0.2);
  EXPECT_LT(r.nrmse_after, 0.03);
  const std::string svg = diagnosis_svg(r, meas);
  EXPECT_NE(svg.find("<svg"), std::string::npos);
  EXPECT_NE(svg.find("dry_run"), std::string::npos);
}

TEST(Diagnosis, BalancePistonWearIsRankedFirstWithItsClearance) {
  const DiagnosisResult r = diagnose(reference_plant(), shared_reference(), case_frf("fault_balance_piston_wear"));
  ASSERT_TRUE(r.detected);
  ASSERT_FALSE(r.faults.empty());
  EXPECT_EQ(r.faults.front().name, "balance_piston_wear");
  // truth.json: clearance 1.6x; magnitude within 20 %.
  EXPECT_NEAR(r.faults.front().value, 1.6, 0.2 * 1.6);
  EXPECT_TRUE(r.explained);
}

TEST(Diagnosis, CrackIsLocatedWithinOneElementAndSized) {
  const DiagnosisResult r = diagnose(reference_plant(), shared_reference(), case_frf("fault_crack"));
  ASSERT_TRUE(r.detected);
  ASSERT_FALSE(r.faults.empty());
  const FaultEstimate& f = r.faults.front();
  ASSERT_EQ(f.name, "rotor_crack");
  // truth.json: element 8, EI factor 0.7 (a stiffness loss of 30 %).
  ASSERT_EQ(f.hypothesis.elements.size(), 1u);
  EXPECT_LE(std::abs(f.hypothesis.elements[0] - 8), 1);
  EXPECT_NEAR(1.0 - f.value, 0.3, 0.2 * 0.3);
  EXPECT_TRUE(r.explained);
  EXPECT_LE(f.ci_lo, f.value);
  EXPECT_GE(f.ci_hi, f.value);
}

// Faults simulated with the fault models at other sizes and places, plus
// noise, against the shared references.
DiagnosisResult diagnose_simulated(const PlantModel& faulty, std::uint64_t seed) {
  const FrfData like = read_frf_csv(data_file("reference_pump/frf_ref_1.csv").string());
  std::mt19937_64 rng(seed);
  const FrfData meas = testing::with_noise(model_frf_like(faulty, like), like, rng);
  return diagnose(reference_plant(), shared_reference(), meas);
}

TEST(Diagnosis, SimulatedCrackNearBearingAIsLocated) {
  const PlantModel plant = reference_plant();
  const auto hs = fault_hypotheses(plant);
  const DiagnosisResult r = diagnose_simulated(apply_fault(plant, *find_hyp(hs, FaultKind::rotor_crack, 4), 0.55), 11);
  ASSERT_TRUE(r.detected);
  ASSERT_EQ(r.faults.front().name, "rotor_crack");
  EXPECT_LE(std::abs(r.faults.front().hypothesis.elements[0] - 4), 1);
  EXPECT_NEAR(1.0 - r.faults.front().value, 0.45, 0.2 * 0.45);
}

// Another seal: the impeller seal's clearance grows; told apart from the
// balance piston and from a partial dry run.
TEST(Diagnosis, SimulatedImpellerSealWearIsToldApartFromThePiston) {
  const PlantModel plant = reference_plant();
  const auto hs = fault_hypotheses(plant);
  const DiagnosisResult r = diagnose_simulated(apply_fault(plant, *find_hyp(hs, FaultKind::impeller_seal_wear), 1.4), 13);
  ASSERT_TRUE(r.detected);
  ASSERT_EQ(r.faults.front().name, "impeller_seal_wear");
  EXPECT_NEAR(r.faults.front().value, 1.4, 0.2 * 1.4);
  EXPECT_TRUE(r.explained);
}

// A sensor gain drift (calibration) changes one row of H: additive, the
// sensor is named, the gain estimated.
TEST(Diagnosis, SensorGainIsIsolatedAsAdditive) {
  const FrfData ref1 = read_frf_csv(data_file("reference_pump/frf_ref_1.csv").string());
  std::mt19937_64 rng(5);
  FrfData meas = testing::with_noise(model_frf_like(reference_plant(), ref1), ref1, rng);
  for (auto& e : meas.entries)
    if (e.output == "xBx")
      for (auto& h : e.h) h *= 0.9;
  const DiagnosisResult r = diagnose(reference_plant(), shared_reference(), meas);
  ASSERT_TRUE(r.detected);
  EXPECT_EQ(r.isolation, "additive_sensor");
  ASSERT_EQ(r.faults.front().name, "sensor_fault");
  EXPECT_EQ(r.faults.front().hypothesis.channel, "xBx");
  EXPECT_NEAR(r.faults.front().value, 0.9, 0.01);
  EXPECT_TRUE(r.explained);
}

// A change no fault model describes (the housing resonance moved) is
// detected and reported as unknown instead of forcing a fault.
TEST(Diagnosis, UnmodelledChangeIsUnknown) {
  PlantModel changed = reference_plant();
  changed.housings.at(0).f_hz *= 1.08;
  const DiagnosisResult r = diagnose_simulated(changed, 7);
  ASSERT_TRUE(r.detected);
  ASSERT_FALSE(r.faults.empty());
  EXPECT_EQ(r.faults.front().name, "unknown");
  EXPECT_FALSE(r.explained);
}

}  // namespace
}  // namespace ambdiag
