// explain's server job (run_analysis.h, explain_run) on what the server
// explains: the FRF its analysis job estimated from a simulated run and
// kept as frf.csv. The run is the web UI's and the fleet fixture's worn
// piston (web_ui_fixture.h: the reference pump, speed spread 2 %, seal drift
// 1 %, seed 4, balance_piston_wear=1.5 from run 4; its run 4), simulated
// here by the edge agent's simulator library.
//
// Before the fix this job returned NRMSE 0.155 -> 0.182: the selection
// accepted steps on the noise-weighted chi2 while the reported NRMSE is
// unweighted, and on a run's estimate sigma is ~5 % of |H| at the rigid-body
// lines where |H| (and the NRMSE) is largest but ~0.3 % around the bending
// modes (where chi2 is); the catalogue could not express the worn piston
// (every coefficient, its fluid mass too, x 1 / clearance), so the chi2 was
// bought around the bending modes at the low lines' expense
// (docs/explain.md, "Guarantee").
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <string>

#include "ambdiag/algorithms/explain/missing_physics.h"
#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/edge_agent/simulate.h"
#include "analysis/run_analysis.h"
#include "test_support.h"

namespace ambdiag::server::detail {
namespace {

using nlohmann::json;

class ExplainRun : public ::testing::Test {
 protected:
  static inline PlantModel nominal, truth;
  static inline FrfData frf;  // as the analysis job kept it

  static void SetUpTestSuite() {
    const std::string model = testing::data_file("reference_pump/plant.json").string();
    nominal = read_plant_file(model);
    agent::SimulationOptions o;
    o.pump_id = "W-2";
    o.faults = {"balance_piston_wear=1.5@run4"};
    o.speed_spread_pct = 2.0;
    o.seal_drift_pct = 1.0;
    o.runs = 4;
    o.seed = 4;
    agent::PumpSimulator sim(model, o);
    RunRecording run;
    for (int i = 0; i < 4; ++i) run = sim.identification_run();
    truth = sim.plant();
    const JobOutput analysis = analyse_run(nominal, run, nullptr, 0.01, nullptr);
    for (const auto& a : analysis.artifacts)
      if (a.name == "frf.csv") frf = parse_frf_csv(a.data, "frf.csv");
  }

  static size_t link_named(const PlantModel& p, const std::string& name) {
    for (size_t i = 0; i < p.links.size(); ++i)
      if (p.links[i].name == name) return i;
    ADD_FAILURE() << "no link " << name;
    return 0;
  }

  // cli.md's NRMSE of a plant JSON (with explain's acquisition delay) on
  // the recording, computed apart from explain: the model FRF on the
  // recording's lines and entries at its speed (frf_compare.h).
  static double nrmse_of(const json& plant_json) {
    const PlantVariant v = variant_from_json(plant_json);
    FrfData model = model_frf_like(v.plant, frf);
    for (auto& e : model.entries)
      for (size_t l = 0; l < e.h.size(); ++l) e.h[l] *= std::polar(1.0, -2 * M_PI * model.freq_hz[l] * v.delay_s);
    return compare_frf(model, frf).nrmse;
  }

  // Every piece lowered the NRMSE it reports; the whole is no worse than the
  // model; before and after are the same figure of the two models.
  static void expect_guarantee(const PlantModel& model, const json& r) {
    EXPECT_LE(r["nrmse_after"].get<double>(), r["nrmse_before"].get<double>()) << r["story"].dump(1);
    for (const auto& e : r["explanations"])
      EXPECT_LT(e["nrmse_after"].get<double>(), e["nrmse_before"].get<double>()) << e.dump();
    EXPECT_NEAR(r["nrmse_before"].get<double>(), nrmse_of(plant_to_json(model)), 1e-6 * r["nrmse_before"].get<double>());
    EXPECT_NEAR(r["nrmse_after"].get<double>(), nrmse_of(r["improved_model"]), 1e-6 * r["nrmse_after"].get<double>());
  }
};

TEST_F(ExplainRun, TheWornPistonsClearanceIsFoundAndTheFitComesToTheNoise) {
  ASSERT_FALSE(frf.entries.empty());
  ASSERT_TRUE(frf.speed_rpm.has_value());
  const json r = explain_run(nominal, frf, nullptr).result;
  expect_guarantee(nominal, r);
  // The truth: every coefficient of the piston x 1 / (1.5 x the seal drift).
  const size_t piston = link_named(nominal, "balance_piston");
  const double factor = truth.links[piston].coef[0] / nominal.links[piston].coef[0];
  ASSERT_NEAR(factor, 1.0 / 1.5, 0.03);
  const std::string prefix = "links[" + std::to_string(piston) + "].";
  int coefficients = 0;
  for (const auto& u : r["updated_parameters"]) {
    const std::string path = u["path"];
    EXPECT_EQ(path.rfind(prefix, 0), 0u) << "only the piston changes: " << u.dump();
    EXPECT_NEAR(u["to"].get<double>() / u["from"].get<double>(), factor, 0.03 * factor) << u.dump();
    ++coefficients;
  }
  EXPECT_EQ(coefficients, 10) << "k, c direct and cross-coupled, and the fluid mass: " << r["updated_parameters"].dump();
  EXPECT_TRUE(r["explanations"].empty()) << "a worn clearance is a correction of the seal, not missing physics: "
                                         << r["explanations"].dump();
  EXPECT_GT(r["nrmse_before"].get<double>(), 2.0 * r["noise_floor_nrmse"].get<double>());
  EXPECT_LT(r["nrmse_after"].get<double>(), 1.1 * r["noise_floor_nrmse"].get<double>());
}

// The same recording against a model whose piston is not marked as a fluid
// seal (`kind` is free text): no clearance change is offered for it, the
// catalogue cannot express the wear, as before the fix. chi2 still falls
// by a lot on pieces that buy it around the bending modes; none of them may
// raise the reported NRMSE. Nor is the wear named as missing physics: the
// truth holds none. (Without the refusal of steps that raise the NRMSE
// beyond the noise the selection buys chi2 with a damper at node 21 and a
// housing mode at 596 Hz, handed out as missing physics.)
TEST_F(ExplainRun, WhatTheCatalogueCannotExpressNeverRaisesTheReportedNrmse) {
  PlantModel unmarked = nominal;
  unmarked.links[link_named(unmarked, "balance_piston")].kind = "annular";
  const json r = explain_run(unmarked, frf, nullptr).result;
  expect_guarantee(unmarked, r);
  EXPECT_LT(r["chi2_per_line_after"].get<double>(), r["chi2_per_line_before"].get<double>());
  EXPECT_TRUE(r["explanations"].empty()) << r["story"].dump(1);
}

}  // namespace
}  // namespace ambdiag::server::detail
