// The reusable parameter-fit piece of explain: evaluator consistency with
// synthesize_frf, and Levenberg-Marquardt recovering parameters concealed in
// noisy data from our own simulator.
#include <gtest/gtest.h>

#include <cmath>

#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/algorithms/model/plant_frf_fit.h"
#include "explain_support.h"
#include "generated_rotor.h"

namespace ambdiag {
namespace {

PlantModel rotor() {
  PlantModel p = testing::generated_rotor(10, {true, 0.005});
  p.housings.push_back({"housing_A", "A", {"x", "y"}, 420.0, 0.04, 50.0});
  p.axial->housings.push_back({"housing_axial", 260.0, 0.03, 80.0});
  return p;
}

std::vector<double> grid() { return frequency_grid(2.0, 600.0, 2.0); }

// The evaluator splits rotor (FE) and closed-form parts; together they must
// equal the full synthesis to round-off.
TEST(PlantFrfFit, EvaluatorEqualsFullSynthesis) {
  const PlantModel p = rotor();
  FrfData full = synthesize_frf(p, p.speed_rpm, grid(), {FrfMethod::modal});
  full.speed_rpm = p.speed_rpm;
  PlantFrfEvaluator eval(full);
  const FrfData m = eval.model_frf({p, 0.0});
  ASSERT_EQ(m.entries.size(), full.entries.size());
  for (size_t e = 0; e < m.entries.size(); ++e) {
    double scale = 0.0;
    for (const auto& h : full.entries[e].h) scale = std::max(scale, std::abs(h));
    for (size_t l = 0; l < m.freq_hz.size(); ++l)
      EXPECT_LE(std::abs(m.entries[e].h[l] - full.entries[e].h[l]), 1e-9 * scale + 1e-30) << e << " " << l;
  }
}

TEST(PlantFrfFit, RecoversAConcealedHousingModeWithinItsStandardDeviation) {
  PlantModel truth = rotor();
  truth.housings.push_back({"hidden", "B", {"x", "y"}, 310.0, 0.025, 35.0});
  const FrfData meas = testing::noisy_recording({truth, 0.0}, grid(), 7);
  PlantFrfEvaluator eval(meas);
  const PlantModel base = rotor();
  auto build = [&](const std::vector<double>& x) {
    PlantVariant v{base, 0.0};
    v.plant.housings.push_back({"fit", "B", {"x", "y"}, x[0], x[1], x[2]});
    return v;
  };
  std::vector<int> lines(meas.freq_hz.size());
  for (size_t l = 0; l < lines.size(); ++l) lines[l] = static_cast<int>(l);
  const auto r = fit_parameters(eval, build, {{"f", 300.0, 100.0, 600.0, 2.0}, {"zeta", 0.04, 0.001, 0.5, 0.005}, {"m", 60.0, 1.0, 1e3, 5.0}},
                                lines);
  EXPECT_TRUE(r.converged) << r.stop_reason;
  const double want[3] = {310.0, 0.025, 35.0};
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(std::isfinite(r.sd[i]));
    EXPECT_NEAR(r.x[i], want[i], 4.0 * r.sd[i]) << i;
    EXPECT_NEAR(r.x[i], want[i], 0.03 * want[i]) << i;
  }
  // At the truth the residual is noise: chi2 per line near 1 (sd sqrt(1/N)).
  const double n = static_cast<double>(lines.size() * meas.entries.size());
  EXPECT_NEAR(r.chi2 / n, 1.0, 5.0 / std::sqrt(n));
  EXPECT_EQ(eval.rotor_solves(), 1);  // housing parameters need no FE solve
}

TEST(PlantFrfFit, RecoversAnAcquisitionDelay) {
  const PlantModel p = rotor();
  const FrfData meas = testing::noisy_recording({p, 45e-6}, grid(), 11);
  PlantFrfEvaluator eval(meas);
  auto build = [&](const std::vector<double>& x) { return PlantVariant{p, x[0]}; };
  std::vector<int> even;
  for (size_t l = 0; l < meas.freq_hz.size(); l += 2) even.push_back(static_cast<int>(l));
  const auto r = fit_parameters(eval, build, {{"tau", 0.0, -1e-3, 1e-3, 1e-6}}, even);
  EXPECT_NEAR(r.x[0], 45e-6, 4.0 * r.sd[0]);
  EXPECT_NEAR(r.x[0], 45e-6, 1e-6);
}

TEST(PlantFrfFit, StaysInsideItsBounds) {
  PlantModel truth = rotor();
  truth.links[0].coef[static_cast<int>(LinkCoef::kxx)] *= 2.0;
  truth.links[0].coef[static_cast<int>(LinkCoef::kyy)] *= 2.0;
  const FrfData meas = testing::noisy_recording({truth, 0.0}, grid(), 3);
  PlantFrfEvaluator eval(meas);
  const PlantModel base = rotor();
  auto build = [&](const std::vector<double>& x) {
    PlantVariant v{base, 0.0};
    v.plant.links[0].coef[static_cast<int>(LinkCoef::kxx)] *= x[0];
    v.plant.links[0].coef[static_cast<int>(LinkCoef::kyy)] *= x[0];
    return v;
  };
  std::vector<int> lines;
  for (size_t l = 0; l < meas.freq_hz.size(); l += 3) lines.push_back(static_cast<int>(l));
  const auto r = fit_parameters(eval, build, {{"factor", 1.0, 0.7, 1.3, 0.05}}, lines);
  EXPECT_DOUBLE_EQ(r.x[0], 1.3);  // the truth (2.0) is outside: the fit ends at the bound
  EXPECT_TRUE(std::isnan(r.sd[0]));
  EXPECT_LT(r.chi2, r.chi2_start);
}

}  // namespace
}  // namespace ambdiag
