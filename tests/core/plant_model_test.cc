#include <functional>
#include "ambdiag/core/plant_model.h"

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "ambdiag/core/error.h"
#include "test_support.h"

namespace ambdiag {
namespace {

using nlohmann::json;

json load_json(const std::filesystem::path& p) {
  std::ifstream in(p);
  return json::parse(in);
}

json reference_doc() { return load_json(testing::data_file("reference_pump/plant.json")); }

// Expects plant_from_json to refuse `doc` with a message containing `fragment`.
void expect_refused(const json& doc, const std::string& fragment) {
  try {
    plant_from_json(doc);
    ADD_FAILURE() << "accepted a bad model; expected: " << fragment;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << "message: " << e.what();
  }
}

TEST(PlantModel, ReadsTheReferencePumpWithEveryPart) {
  const PlantModel p = read_plant_file(testing::data_file("reference_pump/plant.json"));
  EXPECT_EQ(p.shaft.size(), 21u);
  EXPECT_EQ(p.node_count(), 22);
  EXPECT_EQ(p.disks.size(), 4u);
  ASSERT_EQ(p.links.size(), 5u);
  EXPECT_EQ(p.links[0].kind, "seal");
  EXPECT_DOUBLE_EQ(p.links[0].get(LinkCoef::kxy), 23169.2);
  EXPECT_EQ(p.links[0].table.size(), 5u);
  ASSERT_EQ(p.housings.size(), 1u);
  EXPECT_EQ(p.housings[0].dirs, (std::vector<std::string>{"x", "y"}));
  ASSERT_TRUE(p.axial.has_value());
  EXPECT_DOUBLE_EQ(*p.axial->m_kg, 27.246);
  EXPECT_EQ(p.structural_damping.kind, StructuralDamping::Kind::modal);
  EXPECT_EQ(p.sensors.size(), 5u);
  EXPECT_TRUE(p.find_sensor("xZ")->is_axial());
  EXPECT_EQ(*p.find_actuator("fBy")->node, 19);
}

TEST(PlantModel, ReadsEveryPlantFileInTheSharedData) {
  for (const char* f : {"reference_pump/plant.json", "explain_none/nominal.json", "explain_delay/nominal.json",
                        "explain_cross_coupling/nominal.json", "explain_paper_table3/nominal.json"}) {
    EXPECT_NO_THROW(read_plant_file(testing::data_file(f))) << f;
  }
  const json peers = load_json(testing::shared_data() / "../reference/peer-rotor-cases.json");
  for (const auto& c : peers["cases"]) EXPECT_NO_THROW(plant_from_json(c["plant"])) << c["id"];
}

TEST(PlantModel, InterpolatesLinkTablesLinearlyInSpeedAndHoldsOutside) {
  const PlantModel p = read_plant_file(testing::data_file("reference_pump/plant.json"));
  const Link& seal = p.links[0];
  const auto c = [](const LinkCoefficients& v, LinkCoef k) { return v[static_cast<int>(k)]; };
  EXPECT_DOUBLE_EQ(c(seal.at_speed(2950), LinkCoef::kxx), 219000.0);
  EXPECT_NEAR(c(seal.at_speed(1500), LinkCoef::kxx), 0.5 * (25165.2 + 100661.0), 1e-9);
  EXPECT_DOUBLE_EQ(c(seal.at_speed(5000), LinkCoef::kxx), 308273.0);  // held at the end row
  EXPECT_DOUBLE_EQ(c(seal.at_speed(0), LinkCoef::cxx), 75.0);
  // mxx is in no row: the top-level value applies at every speed.
  EXPECT_DOUBLE_EQ(c(seal.at_speed(1000), LinkCoef::mxx), 0.8);
}

TEST(PlantModel, RoundTripsThroughJsonWithoutLoss) {
  const PlantModel a = read_plant_file(testing::data_file("reference_pump/plant.json"));
  const auto path = testing::scratch_dir() / "plant.json";
  write_plant_file(path.string(), a);
  const PlantModel b = read_plant_file(path.string());
  EXPECT_EQ(plant_to_json(a), plant_to_json(b));
  EXPECT_EQ(b.links[1].at_speed(1234.5), a.links[1].at_speed(1234.5));
}

TEST(PlantModel, RefusesOuterDiameterNotAboveInnerNamingTheElement) {
  json d = reference_doc();
  d["shaft"][3]["id"] = 0.05;
  expect_refused(d, "shaft[3].od: must be > id");
}

TEST(PlantModel, RefusesMalformedDocumentsNamingTheField) {
  struct Case {
    std::function<void(json&)> edit;
    std::string fragment;
  };
  const std::vector<Case> cases = {
      {[](json& d) { d["format"] = "ambdiag.plant/2"; }, "format: is \"ambdiag.plant/2\""},
      {[](json& d) { d.erase("format"); }, "format: missing"},
      {[](json& d) { d["shaft"][0]["L"] = 0.0; }, "shaft[0].L: must be > 0"},
      {[](json& d) { d["shaft"][2]["L"] = "long"; }, "shaft[2].L: must be a number"},
      {[](json& d) { d["shaft"][2]["L"] = 1e300; }, "shaft[2].L: must be <= 100 m"},
      {[](json& d) { d["shaft"][1].erase("od"); }, "shaft[1].od: missing"},
      {[](json& d) { d["shaft"][1]["material"] = "brass"; }, "shaft[1].material: names unknown material"},
      {[](json& d) { d["shaft"] = json::array(); }, "shaft: must have at least one element"},
      {[](json& d) { d["disks"][0]["m"] = -3.0; }, "disks[0].m: must be >= 0"},
      {[](json& d) { d["disks"][1]["node"] = 22; }, "disks[1].node: node 22 does not exist"},
      {[](json& d) { d["links"][2]["node"] = -1; }, "links[2].node: node -1 does not exist"},
      {[](json& d) { d["links"][0]["mxx"] = -0.8; }, "links[0].mxx: must be >= 0"},
      {[](json& d) { d["links"][0]["table"][2]["rpm"] = 500.0; }, "links[0].table[2].rpm: must be greater"},
      {[](json& d) { d["links"][1]["name"] = "impeller_seal"; }, "links[1].name: repeats"},
      {[](json& d) { d["housings"][0]["dirs"] = {"z"}; }, "housings[0].dirs[0]: must be \"x\" or \"y\""},
      {[](json& d) { d["housings"][0]["m"] = 0; }, "housings[0].m: must be > 0"},
      {[](json& d) { d["materials"]["steel"]["G"] = 5e10; }, "materials.steel: E and G give Poisson's ratio"},
      {[](json& d) { d["structural_damping"]["kind"] = "rayleigh"; }, "structural_damping.kind: must be"},
      {[](json& d) { d["reduction"] = {{"kind", "modal"}, {"n_elastic_modes", -2}}; }, "reduction.n_elastic_modes"},
      {[](json& d) { d["sensors"][0]["dir"] = "r"; }, "sensors[0].dir: must be"},
      {[](json& d) { d["sensors"][1]["name"] = "xAx"; }, "sensors[1].name: repeats"},
      {[](json& d) { d.erase("axial"); }, "sensors[4]: an axial point (dir z) needs the \"axial\" model"},
      {[](json& d) { d["actuators"][2].erase("node"); }, "actuators[2].node: missing"},
      {[](json& d) { d["shaft"] = 5; }, "shaft: must be an array"},
      {[](json& d) { d["speed_rpm"] = -1; }, "speed_rpm: must be >= 0"},
  };
  for (const auto& c : cases) {
    json d = reference_doc();
    c.edit(d);
    expect_refused(d, c.fragment);
  }
}

TEST(PlantModel, RefusesTruncatedAndNonJsonFilesNamingTheFile) {
  const std::string text = reference_doc().dump();
  const auto path = testing::write_scratch("truncated.json", text.substr(0, text.size() / 2));
  try {
    read_plant_file(path.string());
    FAIL() << "accepted a truncated file";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("truncated.json: invalid JSON"), std::string::npos) << e.what();
  }
  EXPECT_THROW(read_plant_file("/nonexistent/plant.json"), InputError);
  const auto nan_path = testing::write_scratch("nan.json", "{\"format\": \"ambdiag.plant/1\", \"speed_rpm\": NaN}");
  EXPECT_THROW(read_plant_file(nan_path.string()), InputError);
}

}  // namespace
}  // namespace ambdiag
