#include "ambdiag/algorithms/model/modal_analysis.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <numbers>
#include <nlohmann/json.hpp>

#include "ambdiag/core/plant_model.h"
#include "test_support.h"

namespace ambdiag {
namespace {

using nlohmann::json;
constexpr double kTwoPi = 2.0 * std::numbers::pi;

json load_json(const std::filesystem::path& p) {
  std::ifstream in(p);
  return json::parse(in);
}

std::vector<Mode> lateral_modes(const ModalResult& r) {
  std::vector<Mode> out;
  for (const auto& m : r.modes)
    if (m.kind == "rotor" && !m.overdamped && m.f_hz > 0) out.push_back(m);
  return out;
}

// ROSS reference rotors (Friswell et al. examples), within 0.3 %.
TEST(ModalAnalysis, ReproducesPeerRotorCasesWithinPointThreePercent) {
  const json peers = load_json(testing::shared_data() / "../reference/peer-rotor-cases.json");
  int compared = 0;
  for (const auto& c : peers["cases"]) {
    const PlantModel plant = plant_from_json(c["plant"]);
    for (const auto& e : c["expected"]) {
      const double rpm = e["speed_rpm"].get<double>();
      const auto modes = lateral_modes(modal_analysis(plant, rpm));
      const bool damped = e.contains("wd_rad_per_s");
      const auto& ref = damped ? e["wd_rad_per_s"] : e["wn_rad_per_s"];
      // ROSS sorts by the listed quantity.
      std::vector<std::pair<double, double>> got;  // (w, zeta)
      for (const auto& m : modes) {
        const double w = damped ? std::abs(m.eigenvalue.imag()) : std::abs(m.eigenvalue);
        got.emplace_back(w, m.zeta);
      }
      std::sort(got.begin(), got.end());
      ASSERT_GE(got.size(), ref.size()) << c["id"];
      for (size_t i = 0; i < ref.size(); ++i) {
        const double want = ref[i].get<double>();
        EXPECT_NEAR(got[i].first, want, 0.003 * want) << c["id"] << " rpm " << rpm << " mode " << i;
        if (e.contains("zeta")) {
          EXPECT_NEAR(got[i].second, e["zeta"][i].get<double>(), 0.003 * e["zeta"][i].get<double>() + 1e-4)
              << c["id"] << " rpm " << rpm << " mode " << i;
        }
        ++compared;
      }
    }
  }
  EXPECT_GE(compared, 30);
}

// The reference pump's truth modes (independent generator): f within 0.5 %,
// zeta within 3 % relative, whirl direction equal.
TEST(ModalAnalysis, ReproducesReferencePumpTruthModes) {
  const PlantModel plant = read_plant_file(testing::data_file("reference_pump/plant.json"));
  const json truth = load_json(testing::data_file("reference_pump/truth.json"));
  const ModalResult r = modal_analysis(plant, truth["speed_rpm"].get<double>());
  for (const auto& t : truth["truth_modes"]) {
    const double f = t["f_hz"].get<double>();
    const double zeta = t["zeta"].get<double>();
    const Mode* best = nullptr;
    for (const auto& m : r.modes) {
      if (t["whirl"].is_string() && to_string(m.whirl) != t["whirl"].get<std::string>()) continue;
      if (!best || std::abs(m.f_hz - f) < std::abs(best->f_hz - f)) best = &m;
    }
    ASSERT_NE(best, nullptr) << t["label"];
    EXPECT_NEAR(best->f_hz, f, 0.005 * f) << t["label"] << " " << t["whirl"];
    EXPECT_NEAR(best->zeta, zeta, 0.03 * zeta) << t["label"] << " " << t["whirl"];
  }
}

}  // namespace
}  // namespace ambdiag
