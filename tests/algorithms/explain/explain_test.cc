// explain on a small generated rotor (fast): physics concealed in data from
// our own simulator with noise is named and sized; nothing concealed,
// nothing claimed; bands are located where the difference is.
#include <gtest/gtest.h>

#include <cmath>

#include "ambdiag/algorithms/explain/explain.h"
#include "explain_support.h"
#include "generated_rotor.h"

namespace ambdiag {
namespace {

PlantModel rotor() {
  PlantModel p = testing::generated_rotor(10, {true, 0.005});
  p.housings.push_back({"housing_A", "A", {"x", "y"}, 420.0, 0.04, 50.0});
  return p;
}

std::vector<double> grid() { return frequency_grid(2.0, 600.0, 2.0); }

const Explanation* find(const ExplainResult& r, const std::string& physics) {
  for (const auto& e : r.explanations)
    if (e.physics == physics) return &e;
  return nullptr;
}

TEST(Explain, NothingConcealedNothingClaimed) {
  const PlantModel p = rotor();
  const FrfData meas = testing::noisy_recording({p, 0.0}, grid(), 21);
  const ExplainResult r = explain(p, meas);
  EXPECT_TRUE(r.mismatches.empty());
  EXPECT_TRUE(r.explanations.empty());
  EXPECT_TRUE(r.unexplained.empty());
  EXPECT_TRUE(r.updated_parameters.empty());
  EXPECT_NEAR(r.nrmse_after, r.nrmse_before, 1e-12);
  EXPECT_LT(r.nrmse_after, 2.0 * r.noise_floor_nrmse);
}

TEST(Explain, ConcealedHousingModeIsLocatedNamedAndSized) {
  PlantModel truth = rotor();
  truth.housings.push_back({"hidden", "B", {"x", "y"}, 330.0, 0.02, 30.0});
  const FrfData meas = testing::noisy_recording({truth, 0.0}, grid(), 22);
  const ExplainResult r = explain(rotor(), meas);
  ASSERT_FALSE(r.mismatches.empty());
  bool band_at_330 = false;
  for (const auto& m : r.mismatches) band_at_330 |= m.band_lo_hz <= 330.0 && m.band_hi_hz >= 330.0;
  EXPECT_TRUE(band_at_330);
  const Explanation* e = find(r, "housing_mode");
  ASSERT_NE(e, nullptr);
  EXPECT_EQ(e->location["plane"], "B");
  EXPECT_NEAR(e->parameters["f_hz"].get<double>(), 330.0, 0.15 * 330.0 * 0.1);
  EXPECT_NEAR(e->parameters["zeta"].get<double>(), 0.02, 0.15 * 0.02);
  EXPECT_NEAR(e->parameters["m"].get<double>(), 30.0, 0.15 * 30.0);
  EXPECT_EQ(r.explanations.size(), 1u);
  EXPECT_TRUE(r.unexplained.empty());
  EXPECT_LT(r.nrmse_after, 1.3 * r.noise_floor_nrmse);
  // The improved model round-trips through the plant reader.
  const PlantVariant back = variant_from_json(variant_to_json(r.improved));
  EXPECT_EQ(back.plant.housings.size(), 2u);
}

TEST(Explain, ConcealedDelayIsNamedAndRoundTripsAsAnExtension) {
  const PlantModel p = rotor();
  const FrfData meas = testing::noisy_recording({p, 30e-6}, grid(), 23);
  const ExplainResult r = explain(p, meas);
  const Explanation* e = find(r, "acquisition_delay");
  ASSERT_NE(e, nullptr);
  EXPECT_NEAR(e->parameters["seconds"].get<double>(), 30e-6, 0.15 * 30e-6);
  EXPECT_EQ(r.explanations.size(), 1u);
  bool drift = false;
  std::string kinds;
  for (const auto& m : r.mismatches) {
    drift |= m.kind == "phase_drift";
    kinds += m.kind + " " + std::to_string(m.band_lo_hz) + "-" + std::to_string(m.band_hi_hz) + " " + std::to_string(m.entries.size()) + "; ";
  }
  EXPECT_TRUE(drift) << kinds;
  const nlohmann::json j = variant_to_json(r.improved);
  EXPECT_NO_THROW(plant_from_json(j));  // the plain reader accepts it
  EXPECT_NEAR(variant_from_json(j).delay_s, e->parameters["seconds"].get<double>(), 1e-15);
}

TEST(Explain, ParameterWithinBoundsIsAnUpdateNotPhysics) {
  PlantModel truth = rotor();
  truth.axial->c_ns_per_m *= 2.0;
  const FrfData meas = testing::noisy_recording({truth, 0.0}, grid(), 24);
  const ExplainResult r = explain(rotor(), meas);
  EXPECT_TRUE(r.explanations.empty());
  bool found = false;
  for (const auto& u : r.updated_parameters)
    if (u.path == "axial.c") {
      found = true;
      EXPECT_NEAR(u.to, truth.axial->c_ns_per_m, 0.05 * truth.axial->c_ns_per_m);
    }
  EXPECT_TRUE(found);
}

TEST(Explain, JsonHasTheContractKeys) {
  PlantModel truth = rotor();
  truth.housings.push_back({"hidden", "A", {"x", "y"}, 250.0, 0.03, 40.0});
  const FrfData meas = testing::noisy_recording({truth, 0.0}, grid(), 25);
  const nlohmann::json j = explain_to_json(explain(rotor(), meas));
  for (const char* k : {"mismatches", "explanations", "unexplained", "nrmse_before", "nrmse_after", "improved_model", "updated_parameters"})
    EXPECT_TRUE(j.contains(k)) << k;
  ASSERT_FALSE(j["mismatches"].empty());
  for (const char* k : {"outputs", "inputs", "band_hz"}) EXPECT_TRUE(j["mismatches"][0].contains(k)) << k;
  ASSERT_FALSE(j["explanations"].empty());
  for (const char* k : {"physics", "parameters", "location", "nrmse_before", "nrmse_after", "evidence"})
    EXPECT_TRUE(j["explanations"][0].contains(k)) << k;
  EXPECT_NO_THROW(plant_from_json(j["improved_model"]));
}

}  // namespace
}  // namespace ambdiag
