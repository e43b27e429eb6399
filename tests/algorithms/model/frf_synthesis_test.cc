#include "ambdiag/algorithms/model/frf_synthesis.h"

#include <gtest/gtest.h>

#include <cmath>

#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"
#include "test_support.h"

namespace ambdiag {
namespace {

// Mean over lines of |H_model - H_measured|^2 / sigma^2 per entry: about 1
// when the model equals the truth and the file's sigma is its noise.
TEST(FrfSynthesis, ReproducesReferencePumpMeasurementWithinItsNoise) {
  const PlantModel plant = read_plant_file(testing::data_file("reference_pump/plant.json"));
  const FrfData meas = read_frf_csv(testing::data_file("reference_pump/frf_ref_1.csv").string());
  ASSERT_TRUE(meas.speed_rpm.has_value());
  const FrfData model = synthesize_frf(plant, *meas.speed_rpm, meas.freq_hz);
  ASSERT_EQ(meas.entries.size(), 25u);
  for (const auto& me : meas.entries) {
    const FrfEntry* e = model.find(me.output, me.input);
    ASSERT_NE(e, nullptr) << me.output << "/" << me.input;
    ASSERT_EQ(me.sigma.size(), me.h.size());
    double chi2 = 0.0;
    for (size_t l = 0; l < me.h.size(); ++l) chi2 += std::norm(e->h[l] - me.h[l]) / (me.sigma[l] * me.sigma[l]);
    chi2 /= static_cast<double>(me.h.size());
    // 1000 lines: the mean of |n|^2/sigma^2 has a standard deviation of about 0.03.
    EXPECT_GT(chi2, 0.85) << me.output << "/" << me.input;
    EXPECT_LT(chi2, 1.15) << me.output << "/" << me.input;
  }
}

TEST(FrfSynthesis, DirectAndModalMethodsAgree) {
  const PlantModel plant = read_plant_file(testing::data_file("reference_pump/plant.json"));
  const std::vector<double> f = frequency_grid(1.0, 1000.0, 7.0);
  const FrfData direct = synthesize_frf(plant, 2950, f, {FrfMethod::direct});
  const FrfData modal = synthesize_frf(plant, 2950, f, {FrfMethod::modal});
  for (size_t k = 0; k < direct.entries.size(); ++k) {
    double num = 0, den = 0;
    for (size_t l = 0; l < f.size(); ++l) {
      num += std::norm(direct.entries[k].h[l] - modal.entries[k].h[l]);
      den += std::norm(direct.entries[k].h[l]);
    }
    if (den == 0) continue;  // lateral-axial entries are zero in both
    // Round-off of the 176-state eigen-decomposition (modes from 1e2 to 1e6
    // rad/s) limits the modal sum to about 1e-7 on the small cross entries.
    EXPECT_LT(std::sqrt(num / den), 1e-6) << direct.entries[k].output << "/" << direct.entries[k].input;
  }
}

}  // namespace
}  // namespace ambdiag
