// The AMB law and loop: k_i and k_s against finite differences of the
// nonlinear magnet-pair force, Table 1 of the paper, and the closed loop's
// stability check.
#include "ambdiag/algorithms/simulation/amb_loop.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include <nlohmann/json.hpp>

#include "ambdiag/core/error.h"
#include "test_support.h"

namespace ambdiag {
namespace {

// f(i, x) of a differential pair biased with i0, nominal gap s0, whose load
// capacity f_max is reached at twice the bias flux: F0 = f_max / 4 at bias.
double pair_force(const AmbMagnetData& m, double i, double x) {
  const double k = m.max_force_n / 4.0 * m.air_gap_m * m.air_gap_m / (m.bias_current_a * m.bias_current_a);
  const double i0 = m.bias_current_a, s0 = m.air_gap_m;
  return k * ((i0 + i) * (i0 + i) / ((s0 - x) * (s0 - x)) - (i0 - i) * (i0 - i) / ((s0 + x) * (s0 + x)));
}

TEST(AmbLinearisation, MatchesFiniteDifferencesOfTheMagnetPairForce) {
  for (const AmbMagnetData& m : {nordmann_aenis_radial_amb(), nordmann_aenis_axial_amb()}) {
    const AmbLinearisation l = linearise_amb(m);
    const double di = 1e-4 * m.bias_current_a, dx = 1e-4 * m.air_gap_m;
    const double k_i = (pair_force(m, di, 0) - pair_force(m, -di, 0)) / (2 * di);
    const double k_s = (pair_force(m, 0, dx) - pair_force(m, 0, -dx)) / (2 * dx);
    EXPECT_NEAR(l.k_i_n_per_a, k_i, 1e-6 * k_i);
    EXPECT_NEAR(l.k_s_n_per_m, k_s, 1e-6 * k_s);
    // One magnet at twice the bias current, the other off: the load capacity.
    EXPECT_NEAR(pair_force(m, m.bias_current_a, 0), m.max_force_n, 1e-9 * m.max_force_n);
    // Saturation of electrical steel is about 1.2-1.6 T: B_max must be below.
    EXPECT_GT(l.max_flux_t, 0.5);
    EXPECT_LT(l.max_flux_t, 1.3);
  }
}

TEST(AmbLinearisation, DefaultsAreTable1OfThePaper) {
  const auto path = ambdiag::testing::shared_data() / ".." / "reference" / "nordmann-aenis-2004.json";
  std::ifstream in(path);
  if (!in) GTEST_SKIP() << "no " << path;
  const auto amb = nlohmann::json::parse(in).at("table1_technical_data").at("amb");
  const std::pair<const char*, AmbMagnetData> cases[] = {{"radial", nordmann_aenis_radial_amb()},
                                                         {"axial", nordmann_aenis_axial_amb()}};
  for (const auto& [name, m] : cases) {
    const auto& t = amb.at(name);
    EXPECT_DOUBLE_EQ(m.air_gap_m, t.at("air_gap_mm").get<double>() * 1e-3) << name;
    EXPECT_DOUBLE_EQ(m.bias_current_a, t.at("bias_current_A").get<double>()) << name;
    EXPECT_DOUBLE_EQ(m.max_force_n, t.at("force_per_axis_N").get<double>()) << name;
    EXPECT_DOUBLE_EQ(m.pole_area_m2, t.at("pole_area_mm2").get<double>() * 1e-6) << name;
    EXPECT_DOUBLE_EQ(m.turns_per_pole_pair, t.at("windings_per_pole_pair").get<double>()) << name;
  }
}

TEST(AmbLinearisation, RefusesNonPositiveData) {
  AmbMagnetData m = nordmann_aenis_radial_amb();
  m.air_gap_m = 0;
  EXPECT_THROW(linearise_amb(m), InputError);
  m = nordmann_aenis_radial_amb();
  m.bias_current_a = std::nan("");
  EXPECT_THROW(linearise_amb(m), InputError);
}

TEST(AmbLoop, DefaultControllerStabilisesTheReferencePump) {
  const PlantModel plant = read_plant_file(ambdiag::testing::data_file("reference_pump/plant.json").string());
  AmbLoopOptions o;
  const AmbLoop loop(plant, o);
  const AmbLoopReport& r = loop.report();
  EXPECT_LT(r.spectral_radius, 1.0);
  ASSERT_EQ(r.kp_a_per_m.size(), plant.actuators.size());
  for (size_t j = 0; j < plant.actuators.size(); ++j)  // k = k_i kp - k_s
    EXPECT_NEAR(r.k_i_n_per_a[j] * r.kp_a_per_m[j] - r.k_s_n_per_m[j], r.stiffness_n_per_m[j], 1e-6 * r.stiffness_n_per_m[j]);
}

TEST(AmbLoop, RefusesAControllerThatDoesNotStabilise) {
  const PlantModel plant = read_plant_file(ambdiag::testing::data_file("reference_pump/plant.json").string());
  AmbLoopOptions o;
  // Net bearing stiffness -0.9 k_s (kp too small): more than the seals and
  // the coupling hold, the rotor falls into the magnets.
  o.radial_stiffness_n_per_m = -0.9 * linearise_amb(o.radial).k_s_n_per_m;
  try {
    AmbLoop loop(plant, o);
    FAIL() << "spectral radius " << loop.report().spectral_radius;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("does not stabilise"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ambdiag
