// Slow evidence for the diagnosis: the false-alarm rate over 1000 healthy
// machines with fresh references each, and faults of other kinds, sizes and
// places simulated by the fault models plus noise.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "ambdiag/algorithms/diagnosis/diagnosis.h"
#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/algorithms/numerics/chi_square.h"
#include "diagnosis_support.h"
#include "test_support.h"

namespace ambdiag {
namespace {

using testing::data_file;
using testing::reference_plant;

// Each machine: five reference runs and one measurement, all the model FRF
// plus independent noise with the shared sigma. Detections at alpha are
// binomial(1000, alpha): 10 +- 3.1 at 0.01, 50 +- 6.9 at 0.05.
TEST(DiagnosisSlow, FalseAlarmRateOverAThousandMachines) {
  const PlantModel plant = reference_plant();
  const FrfData like = read_frf_csv(data_file("reference_pump/frf_ref_1.csv").string());
  const FrfData clean = model_frf_like(plant, like);
  std::mt19937_64 rng(77);
  DiagnosisOptions opt;
  opt.detect_only = true;
  int at1 = 0, at5 = 0;
  const int n = 1000;
  for (int k = 0; k < n; ++k) {
    std::vector<FrfData> refs;
    for (int i = 0; i < 5; ++i) refs.push_back(testing::with_noise(clean, like, rng));
    const DiagnosisResult r = diagnose(plant, reference_statistics(refs), testing::with_noise(clean, like, rng), opt);
    at1 += r.statistic > chi2_quantile(0.99, r.dof);
    at5 += r.statistic > chi2_quantile(0.95, r.dof);
  }
  RecordProperty("alarms_at_0.01", at1);
  RecordProperty("alarms_at_0.05", at5);
  std::printf("false alarms of %d: %d at alpha 0.01, %d at alpha 0.05\n", n, at1, at5);
  EXPECT_GE(at1, 2);
  EXPECT_LE(at1, 20);
  EXPECT_GE(at5, 30);
  EXPECT_LE(at5, 72);
}

struct Case {
  FaultKind kind;
  int element;  // crack: the element; else -1
  double value;
};

// Unseen-like cases: every kind at other sizes, cracks along the shaft. The
// right kind first, a crack within one element, the size within 20 %
// (of the stiffness loss for cracks and the hub joint, of the clearance
// factor for wear; within 0.1 for the fluid factor of a dry run).
TEST(DiagnosisSlow, SimulatedFaultsOfOtherSizesAndPlaces) {
  const PlantModel plant = reference_plant();
  const auto hs = fault_hypotheses(plant);
  const ReferenceStatistics ref = reference_statistics(testing::reference_runs());
  const FrfData like = read_frf_csv(data_file("reference_pump/frf_ref_1.csv").string());
  std::mt19937_64 rng(99);
  const std::vector<Case> cases = {
      {FaultKind::impeller_seal_wear, -1, 1.8}, {FaultKind::impeller_seal_wear, -1, 1.3}, {FaultKind::balance_piston_wear, -1, 1.25},
      {FaultKind::balance_piston_wear, -1, 2.5}, {FaultKind::dry_run, -1, 0.3},           {FaultKind::dry_run, -1, 0.6},
      {FaultKind::rotor_crack, 2, 0.7},          {FaultKind::rotor_crack, 6, 0.8},          {FaultKind::rotor_crack, 10, 0.75},
      {FaultKind::rotor_crack, 13, 0.6},         {FaultKind::rotor_crack, 16, 0.85},        {FaultKind::shaft_nut_loosening, -1, 0.6}};
  for (const auto& c : cases) {
    const FaultHypothesis* h = nullptr;
    for (const auto& x : hs)
      if (x.kind == c.kind && (c.element < 0 || (x.elements.size() == 1 && x.elements[0] == c.element))) h = &x;
    ASSERT_NE(h, nullptr);
    const FrfData meas = testing::with_noise(model_frf_like(apply_fault(plant, *h, c.value), like), like, rng);
    const DiagnosisResult r = diagnose(plant, ref, meas);
    const std::string what = to_string(c.kind) + " " + std::to_string(c.element) + " " + std::to_string(c.value);
    ASSERT_TRUE(r.detected) << what;
    const FaultEstimate& f = r.faults.front();
    EXPECT_EQ(f.name, to_string(c.kind)) << what;
    EXPECT_TRUE(r.explained) << what;
    if (f.name != to_string(c.kind)) continue;
    if (c.kind == FaultKind::rotor_crack) {
      EXPECT_LE(std::abs(f.hypothesis.elements[0] - c.element), 1) << what;
      EXPECT_NEAR(1.0 - f.value, 1.0 - c.value, 0.2 * (1.0 - c.value)) << what;
    } else if (c.kind == FaultKind::shaft_nut_loosening) {
      EXPECT_NEAR(1.0 - f.value, 1.0 - c.value, 0.2 * (1.0 - c.value)) << what;
    } else if (c.kind == FaultKind::dry_run) {
      EXPECT_NEAR(f.value, c.value, 0.1) << what;
    } else {
      EXPECT_NEAR(f.value, c.value, 0.2 * c.value) << what;
    }
  }
}

// An actuator whose gain dropped (an amplifier fault): additive, the
// actuator named.
TEST(DiagnosisSlow, ActuatorGainIsIsolated) {
  const FrfData like = read_frf_csv(data_file("reference_pump/frf_ref_1.csv").string());
  std::mt19937_64 rng(3);
  FrfData meas = testing::with_noise(model_frf_like(reference_plant(), like), like, rng);
  for (auto& e : meas.entries)
    if (e.input == "fBy")
      for (auto& h : e.h) h *= 1.15;
  const DiagnosisResult r = diagnose(reference_plant(), reference_statistics(testing::reference_runs()), meas);
  ASSERT_TRUE(r.detected);
  EXPECT_EQ(r.isolation, "additive_actuator");
  ASSERT_EQ(r.faults.front().name, "actuator_fault");
  EXPECT_EQ(r.faults.front().hypothesis.channel, "fBy");
  EXPECT_NEAR(r.faults.front().value, 1.15, 0.01);
}

}  // namespace
}  // namespace ambdiag
