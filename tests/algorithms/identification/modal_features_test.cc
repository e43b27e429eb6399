// Modal features as symptoms: reference modes from several healthy runs,
// their normalised shifts in a measured run (the paper's Table 4).
#include <gtest/gtest.h>

#include <cmath>

#include "ambdiag/algorithms/identification/modal_features.h"
#include "ambdiag/core/error.h"
#include "diagnosis_support.h"
#include "test_support.h"

namespace ambdiag {
namespace {

using testing::data_file;

std::vector<FrfData> three_runs() {
  std::vector<FrfData> v;
  for (int i = 1; i <= 3; ++i) v.push_back(read_frf_csv(data_file("reference_pump/frf_ref_" + std::to_string(i) + ".csv").string()));
  return v;
}

const ModalFeatureReference& reference() {
  static const ModalFeatureReference r = modal_feature_reference(three_runs());
  return r;
}

// Healthy runs agree within their ML uncertainty: the modes found in every
// run include the radial bending modes, and a fourth healthy run is not
// detected by the feature test.
TEST(ModalFeatures, HealthyRunsAgreeAndAFourthIsNotDetected) {
  const ModalFeatureReference& ref = reference();
  EXPECT_EQ(ref.runs, 3);
  ASSERT_GE(ref.modes.size(), 4u);
  int bending = 0;
  for (const auto& m : ref.modes) bending += m.direction == "radial" && m.f_hz > 150.0;
  EXPECT_GE(bending, 3);
  const FrfData fourth = read_frf_csv(data_file("reference_pump/frf_ref_4.csv").string());
  const ModalFeatureTest t = modal_feature_test(ref, fourth, 0.01);
  EXPECT_FALSE(t.detected) << "statistic " << t.statistic << " threshold " << t.threshold;
}

// Dry run: the rotor modes move far beyond their scatter (the paper's
// Table 4: bending 1 from 184 to 301 Hz); the test fires.
TEST(ModalFeatures, DryRunShiftsTheRotorModes) {
  const ModalFeatureTest t = modal_feature_test(reference(), read_frf_csv(data_file("fault_dry_run/frf.csv").string()), 0.01);
  EXPECT_TRUE(t.detected);
  double largest = 0.0;
  for (const auto& s : t.shifts) largest = std::max(largest, std::fabs(s.z_f));
  EXPECT_GT(largest, 10.0);
}

TEST(ModalFeatures, NeedsTwoRuns) {
  EXPECT_THROW(modal_feature_reference({three_runs().front()}), InputError);
}

}  // namespace
}  // namespace ambdiag
