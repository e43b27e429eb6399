// explain on the independent generator's cases (../shared/data/explain_*)
// and on the reference pump with physics concealed by our own simulator:
// every concealed effect named with parameters within 15 %, NRMSE after
// near the noise floor, nothing claimed when nothing is concealed.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>

#include "ambdiag/algorithms/explain/explain.h"
#include "explain_support.h"
#include "test_support.h"

namespace ambdiag {
namespace {

using nlohmann::json;

json read_json(const std::string& path) {
  std::ifstream in(path);
  return json::parse(in);
}

bool within(double got, double want, double rel = 0.15) { return std::abs(got - want) <= rel * std::abs(want); }

const Explanation* find_explanation(const ExplainResult& r, const std::string& physics,
                                    const std::function<bool(const Explanation&)>& pred) {
  for (const auto& e : r.explanations)
    if (e.physics == physics && pred(e)) return &e;
  return nullptr;
}

double updated(const ExplainResult& r, const std::string& path, double fallback) {
  for (const auto& u : r.updated_parameters)
    if (u.path == path) return u.to;
  return fallback;
}

// Checks every concealed effect of a truth.json against the result.
void expect_effects_explained(const ExplainResult& r, const json& truth, const PlantModel& nominal) {
  for (const auto& eff : truth["concealed_effects"]) {
    const std::string kind = eff["effect"];
    SCOPED_TRACE(eff.dump());
    if (kind == "seal_cross_coupling") {
      const Explanation* e = find_explanation(r, kind, [&](const Explanation& x) { return x.location["link"] == eff["link"]; });
      ASSERT_NE(e, nullptr);
      EXPECT_TRUE(within(e->parameters["k"], eff["k"])) << e->parameters;
      EXPECT_TRUE(within(e->parameters["c"], eff["c"])) << e->parameters;
    } else if (kind == "acquisition_delay") {
      const Explanation* e = find_explanation(r, kind, [](const Explanation&) { return true; });
      ASSERT_NE(e, nullptr);
      EXPECT_TRUE(within(e->parameters["seconds"], eff["seconds"])) << e->parameters;
    } else if (kind == "housing_mode") {
      const double f = eff["f_hz"];
      const Explanation* e = find_explanation(r, kind, [&](const Explanation& x) {
        return x.location["plane"] == eff["plane"] && within(x.parameters["f_hz"], f, 0.02);
      });
      ASSERT_NE(e, nullptr);
      EXPECT_TRUE(within(e->parameters["zeta"], eff["zeta"])) << e->parameters;
      EXPECT_TRUE(within(e->parameters["m"], eff["m"])) << e->parameters;
    } else if (kind == "added_mass") {
      const Explanation* e = find_explanation(r, kind, [&](const Explanation& x) { return x.location["node"] == eff["node"]; });
      ASSERT_NE(e, nullptr);
      EXPECT_TRUE(within(e->parameters["kg"], eff["kg"])) << e->parameters;
      EXPECT_TRUE(within(e->parameters["Id"], eff["Id"])) << e->parameters;
    } else if (kind == "axial_change") {
      EXPECT_TRUE(within(updated(r, "axial.k", nominal.axial->k_n_per_m), eff["k"]));
      EXPECT_TRUE(within(updated(r, "axial.c", nominal.axial->c_ns_per_m), eff["c"]));
    } else {
      ADD_FAILURE() << "test does not know effect " << kind;
    }
  }
}

ExplainResult run_case(const std::string& name, json* truth, PlantModel* nominal) {
  *nominal = read_plant_file(testing::data_file(name + "/nominal.json").string());
  *truth = read_json(testing::data_file(name + "/truth.json").string());
  const FrfData meas = read_frf_csv(testing::data_file(name + "/frf.csv").string());
  return explain(*nominal, meas);
}

class ExplainSharedCase : public ::testing::TestWithParam<std::string> {};

TEST_P(ExplainSharedCase, NamesTheConcealedPhysicsAndReachesTheNoiseFloor) {
  json truth;
  PlantModel nominal;
  const ExplainResult r = run_case(GetParam(), &truth, &nominal);
  expect_effects_explained(r, truth, nominal);
  // No physics claimed beyond what was concealed (updates are separate).
  size_t concealed_physics = 0;
  for (const auto& eff : truth["concealed_effects"]) concealed_physics += eff["effect"] != "axial_change";
  EXPECT_EQ(r.explanations.size(), concealed_physics);
  EXPECT_TRUE(r.unexplained.empty());
  EXPECT_LT(r.nrmse_after, 1.25 * r.noise_floor_nrmse) << r.nrmse_after << " floor " << r.noise_floor_nrmse;
  if (truth["concealed_effects"].empty()) {
    EXPECT_TRUE(r.mismatches.empty());
    EXPECT_TRUE(r.updated_parameters.empty());
  } else {
    EXPECT_FALSE(r.mismatches.empty());
    // The excess over the noise at least halves (NRMSE includes the noise,
    // so a small effect such as a 60 us delay cannot halve it).
    EXPECT_GT(r.chi2_per_line_before - 1.0, 2.0 * (r.chi2_per_line_after - 1.0));
  }
  EXPECT_NO_THROW(plant_from_json(explain_to_json(r)["improved_model"]));
}

INSTANTIATE_TEST_SUITE_P(Cases, ExplainSharedCase,
                         ::testing::Values("explain_cross_coupling", "explain_delay", "explain_paper_table3", "explain_none"));

// Our own concealments on the reference pump, at other places and sizes,
// near other modes, and two at once.
PlantModel pump() { return read_plant_file(testing::data_file("explain_none/nominal.json").string()); }

ExplainResult conceal(const PlantVariant& truth, unsigned seed) {
  const FrfData meas = testing::noisy_recording(truth, frequency_grid(1.0, 1000.0, 1.0), seed);
  ExplainOptions opt;
  if (std::getenv("AMBDIAG_EXPLAIN_TRACE"))  // the selection steps, for a failing case
    opt.progress = [](const std::string& s) { std::fprintf(stderr, "explain: %s\n", s.c_str()); };
  return explain(pump(), meas, opt);
}

size_t link_index(const PlantModel& p, const std::string& name) {
  for (size_t i = 0; i < p.links.size(); ++i)
    if (p.links[i].name == name) return i;
  return 0;
}

// Adds kxy = -kyx = k and cxy = -cyx = c to a link at top level and in its
// speed table (the table overrides the top level where it states a value).
void add_cross_coupling(Link& l, double k, double c) {
  for (auto* row : {&l.coef}) {
    (*row)[1] += k;
    (*row)[2] -= k;
    (*row)[5] += c;
    (*row)[6] -= c;
  }
  for (auto& row : l.table) {
    if (row.values[1]) *row.values[1] += k;
    if (row.values[2]) *row.values[2] -= k;
    if (row.values[5]) *row.values[5] += c;
    if (row.values[6]) *row.values[6] -= c;
  }
}

TEST(ExplainConcealed, CrossCouplingAtTheBalancePiston) {
  PlantVariant t{pump(), 0.0};
  Link& l = t.plant.links[link_index(t.plant, "balance_piston")];
  const double k = 0.4 * l.at_speed(t.plant.speed_rpm)[0], c = 400.0;
  add_cross_coupling(l, k, c);
  const ExplainResult r = conceal(t, 31);
  const Explanation* e = find_explanation(r, "seal_cross_coupling", [](const Explanation& x) { return x.location["link"] == "balance_piston"; });
  ASSERT_NE(e, nullptr);
  EXPECT_TRUE(within(e->parameters["k"], k)) << e->parameters;
  EXPECT_LT(r.nrmse_after, 1.25 * r.noise_floor_nrmse);
}

TEST(ExplainConcealed, HousingModeNextToABendingModeWithADelay) {
  PlantVariant t{pump(), 25e-6};
  t.plant.housings.push_back({"hidden_B", "B", {"x", "y"}, 640.0, 0.02, 50.0});  // next to bending 2 (596/614 Hz)
  const ExplainResult r = conceal(t, 32);
  const Explanation* h = find_explanation(r, "housing_mode", [](const Explanation& x) { return x.location["plane"] == "B"; });
  ASSERT_NE(h, nullptr);
  EXPECT_TRUE(within(h->parameters["f_hz"], 640.0, 0.01));
  EXPECT_TRUE(within(h->parameters["m"], 50.0));
  const Explanation* d = find_explanation(r, "acquisition_delay", [](const Explanation&) { return true; });
  ASSERT_NE(d, nullptr);
  EXPECT_TRUE(within(d->parameters["seconds"], 25e-6));
  EXPECT_EQ(r.explanations.size(), 2u);
  EXPECT_LT(r.nrmse_after, 1.25 * r.noise_floor_nrmse);
}

TEST(ExplainConcealed, AddedMassAtTheThrustDiskWithCrossCoupling) {
  PlantVariant t{pump(), 0.0};
  t.plant.disks.push_back({"hidden", 6, 1.5, 0.004, 0.0});
  add_cross_coupling(t.plant.links[link_index(t.plant, "impeller_seal")], 50000.0, 0.0);
  const ExplainResult r = conceal(t, 33);
  const Explanation* m = find_explanation(r, "added_mass", [](const Explanation& x) { return x.location["node"] == 6; });
  ASSERT_NE(m, nullptr);
  EXPECT_TRUE(within(m->parameters["kg"], 1.5)) << m->parameters;
  const Explanation* c = find_explanation(r, "seal_cross_coupling", [](const Explanation& x) { return x.location["link"] == "impeller_seal"; });
  ASSERT_NE(c, nullptr);
  EXPECT_TRUE(within(c->parameters["k"], 50000.0)) << c->parameters;
  EXPECT_LT(r.nrmse_after, 1.25 * r.noise_floor_nrmse);
}

TEST(ExplainConcealed, SensorNonCollocation) {
  PlantVariant t{pump(), 0.0};
  for (auto& s : t.plant.sensors)
    if (s.plane == "B") *s.node += 1;
  const ExplainResult r = conceal(t, 34);
  const Explanation* e = find_explanation(r, "sensor_noncollocation", [](const Explanation& x) { return x.location["plane"] == "B"; });
  ASSERT_NE(e, nullptr);
  EXPECT_EQ(e->location["node_to"], 18);
  EXPECT_LT(r.nrmse_after, 1.25 * r.noise_floor_nrmse);
}

const Explanation* single(const ExplainResult& r, const std::string& physics) {
  std::string names;
  for (const auto& e : r.explanations) names += e.physics + " " + e.location.dump() + " " + e.parameters.dump() + "; ";
  EXPECT_EQ(r.explanations.size(), 1u) << names;
  const Explanation* e = find_explanation(r, physics, [](const Explanation&) { return true; });
  EXPECT_NE(e, nullptr) << names;
  return e;
}

void scale_link(Link& l, int first, int second, double factor) {
  for (int c : {first, second}) {
    l.coef[static_cast<size_t>(c)] *= factor;
    for (auto& row : l.table)
      if (row.values[static_cast<size_t>(c)]) *row.values[static_cast<size_t>(c)] *= factor;
  }
}

TEST(ExplainConcealed, NothingConcealedNothingClaimedOnThePump) {
  const ExplainResult r = conceal({pump(), 0.0}, 35);
  EXPECT_TRUE(r.explanations.empty());
  EXPECT_TRUE(r.updated_parameters.empty());
  EXPECT_TRUE(r.unexplained.empty());
}

TEST(ExplainConcealed, CouplingStiffnessOfThePump) {
  PlantVariant t{pump(), 0.0};
  scale_link(t.plant.links[link_index(t.plant, "coupling")], 0, 3, 3.0);
  const ExplainResult r = conceal(t, 36);
  if (const Explanation* e = single(r, "coupling_stiffness")) {
    EXPECT_TRUE(within(e->parameters["stiffness_factor"], 3.0)) << e->parameters;
  }
  EXPECT_LT(r.nrmse_after, 1.25 * r.noise_floor_nrmse);
}

TEST(ExplainConcealed, StiffnessChangeOfAMechanicalSeal) {
  PlantVariant t{pump(), 0.0};
  scale_link(t.plant.links[link_index(t.plant, "mechanical_seal_2")], 0, 3, 3.0);
  const ExplainResult r = conceal(t, 37);
  if (const Explanation* e = single(r, "stiffness_change")) {
    EXPECT_EQ(e->location["link"], "mechanical_seal_2");
    EXPECT_TRUE(within(e->parameters["stiffness_factor"], 3.0)) << e->parameters;
  }
  EXPECT_LT(r.nrmse_after, 1.25 * r.noise_floor_nrmse);
}

TEST(ExplainConcealed, DampingOfTheBalancePiston) {
  PlantVariant t{pump(), 0.0};
  scale_link(t.plant.links[link_index(t.plant, "balance_piston")], 4, 7, 0.25);
  const ExplainResult r = conceal(t, 38);
  if (const Explanation* e = single(r, "damping")) {
    EXPECT_EQ(e->location["link"], "balance_piston");
    EXPECT_TRUE(within(e->parameters["damping_factor"], 0.25)) << e->parameters;
  }
  EXPECT_LT(r.nrmse_after, 1.25 * r.noise_floor_nrmse);
}

TEST(ExplainConcealed, GyroscopicWithAHousingMode) {
  PlantVariant t{pump(), 0.0};
  for (auto& d : t.plant.disks) d.ip_kg_m2 *= 3.0;
  t.plant.housings.push_back({"hidden_A", "A", {"x", "y"}, 520.0, 0.03, 60.0});
  const ExplainResult r = conceal(t, 39);
  const Explanation* g = find_explanation(r, "gyroscopic", [](const Explanation&) { return true; });
  ASSERT_NE(g, nullptr);
  EXPECT_TRUE(within(g->parameters["Ip_factor"], 3.0)) << g->parameters;
  const Explanation* h = find_explanation(r, "housing_mode", [](const Explanation& x) { return x.location["plane"] == "A"; });
  ASSERT_NE(h, nullptr);
  EXPECT_TRUE(within(h->parameters["f_hz"], 520.0, 0.01));
  EXPECT_TRUE(within(h->parameters["m"], 60.0));
  EXPECT_EQ(r.explanations.size(), 2u);
}

}  // namespace
}  // namespace ambdiag
