// The concealed cases of issue 18 (concealed_cases.h) are what they claim:
// the absorber's Woodbury update on the rotor receptance agrees with the
// plain synthesis where both apply, and every concealment leaves a mismatch
// beyond the noise (the omitted coupling a large one).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "ambdiag/algorithms/explain/explain.h"
#include "ambdiag/algorithms/model/frf_compare.h"
#include "concealed_cases.h"

namespace ambdiag {
namespace {

using testing::Absorber;
using testing::absorber_receptance;

// Largest |a - b| over the lateral entries, relative to the largest |b|.
double lateral_difference(const std::vector<std::vector<std::complex<double>>>& a, const FrfData& b, const PlantModel& p) {
  double diff = 0.0, scale = 0.0;
  for (size_t e = 0; e < b.entries.size(); ++e) {
    if (p.find_sensor(b.entries[e].output)->is_axial() || p.find_actuator(b.entries[e].input)->is_axial()) continue;
    for (size_t l = 0; l < b.freq_hz.size(); ++l) {
      diff = std::max(diff, std::abs(a[e][l] - b.entries[e].h[l]));
      scale = std::max(scale, std::abs(b.entries[e].h[l]));
    }
  }
  return diff / scale;
}

// The lateral rotor alone: housings add to the synthesized FRF, not to the receptance.
PlantModel rotor_only(PlantModel p) {
  p.housings.clear();
  return p;
}

TEST(ConcealedCases, ReceptanceWithAMasslessAbsorberIsTheSynthesizedFrf) {
  for (const auto& machine : testing::concealed_machines()) {
    SCOPED_TRACE(machine);
    const PlantModel p = rotor_only(testing::concealed_machine(testing::reference_pump_model(), machine));
    const FrfData h = synthesize_frf(p, p.speed_rpm, frequency_grid(1.0, 1000.0, 1.0), {FrfMethod::modal});
    const auto ar = absorber_receptance(p, p.speed_rpm, h, Absorber{10, 0.0, 1e6, 10.0});
    EXPECT_LT(lateral_difference(ar.g, h, p), 1e-8);
    EXPECT_LT(lateral_difference(ar.g_abs, h, p), 1e-8);
  }
}

TEST(ConcealedCases, RigidAbsorberIsAPointMassAtItsNode) {
  for (const auto& machine : testing::concealed_machines()) {
    SCOPED_TRACE(machine);
    PlantModel p = rotor_only(testing::concealed_machine(testing::reference_pump_model(), machine));
    const std::vector<double> grid = frequency_grid(1.0, 1000.0, 1.0);
    // k w^-2 / m = 1e12 / 4e7 / 1.4: the spring's own compliance is 2e-5 of the mass's.
    const Absorber rigid{10, 1.4, 1e12, 0.0};
    const FrfData h = synthesize_frf(p, p.speed_rpm, grid, {FrfMethod::modal});
    const auto ar = absorber_receptance(p, p.speed_rpm, h, rigid);
    p.disks.push_back({"point_mass", 10, 1.4, 0.0, 0.0});
    const FrfData with_mass = synthesize_frf(p, p.speed_rpm, grid, {FrfMethod::modal});
    EXPECT_GT(lateral_difference(ar.g, with_mass, p), 1e-2);  // the mass matters
    EXPECT_LT(lateral_difference(ar.g_abs, with_mass, p), 1e-3);
  }
}

TEST(ConcealedCases, EveryConcealmentShowsBeyondTheNoise) {
  for (const auto& c : testing::concealed_cases(testing::reference_pump_model())) {
    SCOPED_TRACE(c.name);
    const FrfComparison before = compare_frf(model_frf_like(c.nominal, c.measured), c.measured);
    const double chi2_per_value = before.chi2 / before.chi2_lines;  // 1 for a right model
    EXPECT_GT(chi2_per_value, 1.5) << "NRMSE " << before.nrmse;
    std::printf("%-36s NRMSE before %.4f, chi2 per value %.1f\n", c.name.c_str(), before.nrmse, chi2_per_value);
    if (c.effect == "coupling_omitted") {
      EXPECT_GT(before.nrmse, 2.0);
    }
    if (c.absorber) {
      EXPECT_NEAR(c.extra_mode_hz, c.absorber->f_hz(), 0.06 * c.absorber->f_hz());
      EXPECT_NEAR(c.absorber->zeta(), 0.01, 1e-12);
    }
  }
}

// The absorber's own mode stands out of the noise even after the best a
// rigid mass could do (the same mass fixed to the node, which is what the
// absorber looks like below its tuning): in the 9-line windows around its
// mode the mean |r|^2 is far above explain's band threshold of 4.
TEST(ConcealedCases, AbsorberModeIsNotAnAddedMass) {
  for (const auto& machine : testing::concealed_machines()) {
    SCOPED_TRACE(machine);
    const testing::ConcealedCase c = testing::concealed_case(testing::reference_pump_model(), machine, "absorber");
    PlantModel rigid = c.truth;
    rigid.disks.push_back({"absorber_as_mass", c.absorber->node, c.absorber->m_kg, 0.0, 0.0});
    const FrfData h = model_frf_like(rigid, c.measured);
    double worst = 0.0;  // over entries and windows near the mode
    const size_t n = c.measured.freq_hz.size();
    for (size_t e = 0; e < c.measured.entries.size(); ++e)
      for (size_t l = 4; l + 4 < n; ++l) {
        if (std::abs(c.measured.freq_hz[l] - c.extra_mode_hz) > 0.03 * c.extra_mode_hz) continue;
        double s = 0.0;
        for (size_t j = l - 4; j <= l + 4; ++j)
          s += std::norm((h.entries[e].h[j] - c.measured.entries[e].h[j]) / c.measured.entries[e].sigma[j]);
        worst = std::max(worst, s / 9.0);
      }
    std::printf("%s: absorber mode at %.0f Hz, 9-line mean |r|^2 against a rigid mass up to %.1f\n", c.name.c_str(), c.extra_mode_hz, worst);
    EXPECT_GT(worst, 20.0);
  }
}

// Explain's target on the quickest concealed case (the others run in
// explain_concealed_slow_test.cc): the omitted disk polar inertias are
// named as gyroscopic and nothing else is claimed.
TEST(ExplainConcealedQuick, GyroscopicOmittedOnTheReferencePump) {
  const testing::ConcealedCase c = testing::concealed_case(testing::reference_pump_model(), "reference_pump", "gyroscopic_omitted");
  const ExplainResult r = explain(c.nominal, c.measured);
  for (const auto& f : testing::concealed_verdict(c, r)) ADD_FAILURE() << c.name << ": " << f;
}

// What the catalogue cannot express, through the JSON a plant system
// reads: no physics claimed, and the unexplained band holding the
// absorber's mode says where and what (the resonant attachment's node,
// tuning and mass; tolerances: the fit recovers them to well under 1 % at
// 1 % noise, see docs/explain.md, 5 % leaves room for other seeds).
TEST(ExplainConcealedQuick, AbsorberIsUnexplainedAndLocatedInTheJson) {
  const testing::ConcealedCase c = testing::concealed_case(testing::reference_pump_model(), "reference_pump", "absorber");
  ASSERT_TRUE(c.absorber);
  const nlohmann::json j = explain_to_json(explain(c.nominal, c.measured));
  EXPECT_TRUE(j["explanations"].empty()) << j["explanations"].dump();
  const nlohmann::json* located = nullptr;
  for (const auto& u : j["unexplained"]) {
    const double lo = u["band_hz"][0], hi = u["band_hz"][1];
    if (lo <= c.extra_mode_hz && c.extra_mode_hz <= hi && u.contains("located")) located = &u["located"];
  }
  ASSERT_NE(located, nullptr) << j["unexplained"].dump();
  EXPECT_EQ((*located)["node"], c.absorber->node);
  EXPECT_NEAR((*located)["f_hz"].get<double>(), c.absorber->f_hz(), 0.05 * c.absorber->f_hz());
  EXPECT_NEAR((*located)["kg"].get<double>(), c.absorber->m_kg, 0.05 * c.absorber->m_kg);
}

}  // namespace
}  // namespace ambdiag
