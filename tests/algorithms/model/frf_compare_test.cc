#include <gtest/gtest.h>

#include <cmath>

#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/core/error.h"
#include "test_support.h"

namespace ambdiag {
namespace {

PlantModel pump() { return read_plant_file(testing::data_file("reference_pump/plant.json").string()); }
FrfData ref1() { return read_frf_csv(testing::data_file("reference_pump/frf_ref_1.csv").string()); }

// The independent generator's noise is complex Gaussian with the stated
// sigma, so chi2 / lines of the right model is 1 within sqrt(1 / lines):
// with 25 entries of ~1000 lines, 1 +- 0.007; 5 % allows for the model's
// own 0.01 % frequency agreement.
TEST(FrfCompare, RightModelSitsAtTheNoiseFloor) {
  const FrfData meas = ref1();
  const FrfComparison c = compare_frf(model_frf_like(pump(), meas), meas);
  ASSERT_EQ(c.entries.size(), meas.entries.size());
  EXPECT_NEAR(c.chi2 / c.chi2_lines, 1.0, 0.05);
  // 1 % noise of each entry's RMS; the axial-lateral entries are pure noise
  // (model 0, nrmse 1) but tiny, so they do not move the overall figure.
  EXPECT_GT(c.nrmse, 0.005);
  EXPECT_LT(c.nrmse, 0.02);
}

TEST(FrfCompare, WrongModelIsFarAboveTheFloor) {
  const FrfData meas = ref1();
  PlantModel p = pump();
  for (auto& [name, m] : p.materials) m.e_pa *= 0.9;
  const FrfComparison c = compare_frf(model_frf_like(p, meas), meas);
  const FrfComparison right = compare_frf(model_frf_like(pump(), meas), meas);
  // E 10 % low moves the bending modes 5 %: far beyond noise in chi2, and
  // the nrmse (dominated by the bearing-controlled rigid-body modes) at
  // least doubles.
  EXPECT_GT(c.chi2 / c.chi2_lines, 10.0);
  EXPECT_GT(c.nrmse, 2.0 * right.nrmse);
}

TEST(FrfCompare, NrmseFollowsTheCliDefinition) {
  FrfData a;
  a.freq_hz = {1.0, 2.0};
  a.entries = {{"x", "f", {{3.0, 0.0}, {0.0, 4.0}}, {}, {}}};
  FrfData b = a;
  b.entries[0].h = {{3.0, 1.0}, {0.0, 3.0}};  // |dH| = 1, 1; RMS |H_meas| = sqrt(12.5)
  const FrfComparison c = compare_frf(b, a);
  EXPECT_NEAR(c.nrmse, 1.0 / std::sqrt(12.5), 1e-15);
  EXPECT_TRUE(std::isnan(c.entries[0].chi2));
  EXPECT_EQ(c.chi2_lines, 0);
}

TEST(FrfCompare, RefusesForeignEntriesAndGrids) {
  FrfData meas = ref1();
  meas.entries[0].output = "no_such_sensor";
  EXPECT_THROW(model_frf_like(pump(), meas), InputError);
  FrfData a = ref1(), b = ref1();
  b.freq_hz[3] += 0.5;
  EXPECT_THROW(compare_frf(a, b), InputError);
}

}  // namespace
}  // namespace ambdiag
