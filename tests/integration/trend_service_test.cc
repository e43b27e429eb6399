// Trends with real processes: `ambdiag-agent simulate` streams a pump whose
// balance piston wears over its last runs into `ambdiag serve`; its first
// three runs become the reference while it streams, so runs analysed before
// are analysed again. Over REST: one point per run and series (the newest
// analysis, with detection), at each run's start, the reference band from
// the three reference runs, the wear rising in the fault's series, the
// detections as Grafana annotations.
#include "fleet_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(FleetTest, TrendsOfAWearingPistonReadOverRest) {
  const auto runs = run_fleet({{"S-1", second_model, 5, 3.0, 1.5, 9, {"balance_piston_wear=1.35..1.6@run4..5"}}}, 1, 0.1);
  ASSERT_EQ(runs.size(), 5u);
  const std::string fault_series = "fault.balance_piston_wear.clearance_factor";

  const auto list = json_of(get("/api/v1/pumps/S-1/series"));
  std::map<std::string, std::string> units;
  for (const auto& s : list["series"]) units[s["name"]] = s["unit"];
  EXPECT_EQ(units.count("detection.ratio"), 1u) << list.dump();
  EXPECT_EQ(units.count("fit.nrmse"), 1u);
  EXPECT_EQ(units.count(fault_series), 1u) << list.dump();
  int mode_series = 0;
  for (const auto& [name, unit] : units)
    if (name.starts_with("mode.") && name.ends_with(".f_hz")) mode_series += unit == "Hz";
  EXPECT_GE(mode_series, 2);

  auto r = get("/api/v1/pumps/S-1/trends?series=detection.ratio&series=" + server::url_encode_segment(fault_series));
  ASSERT_EQ(r->status, 200) << r->body;
  const auto j = json_of(r);
  const auto& ratio = j["series"][0];
  ASSERT_EQ(ratio["points"].size(), 5u) << ratio.dump();  // one per run: re-analysis replaced, not added
  for (size_t i = 0; i < 5; ++i) {
    const auto& p = ratio["points"][i];
    const auto& o = runs[i];
    EXPECT_EQ(p["run_id"], o.run_id);
    const auto run = json_of(get(run_url(o.run_id)));
    EXPECT_EQ(storage::ns_from_utc(p["time"], "time"), storage::ns_from_utc(run["started_at"], "started_at"));
    // The newest analysis, against the reference: its ratio.
    EXPECT_NEAR(p["value"].get<double>(), o.analysis["detection"]["ratio"].get<double>(), 1e-9) << o.run_id;
    EXPECT_EQ(p["value"].get<double>() > 1.0, o.analysis["detection"]["detected"].get<bool>());
  }
  EXPECT_EQ(ratio["reference"]["runs"], 3);
  EXPECT_LT(ratio["reference"]["mean"].get<double>(), 1.0);
  const auto& wear = j["series"][1]["points"];
  ASSERT_EQ(wear.size(), 2u) << j["series"][1].dump();  // diagnosed runs 4 and 5
  EXPECT_EQ(wear[0]["run_id"], runs[3].run_id);
  EXPECT_GT(wear[1]["value"].get<double>(), wear[0]["value"].get<double>());
  EXPECT_NEAR(wear[1]["value"].get<double>(), 1.6, 0.2);
  EXPECT_TRUE(wear[1].contains("sd"));

  // Two diagnosed runs: no prognosis yet, said so.
  const auto prog = json_of(get("/api/v1/pumps/S-1/prognosis?series=" + server::url_encode_segment(fault_series)));
  EXPECT_EQ(prog["status"], "not enough points") << prog.dump();

  httplib::Client c("127.0.0.1", port);
  const auto ann = c.Post("/api/v1/grafana/annotations", {{"Authorization", "Bearer " + tokens.at("viewer")}},
                          R"({"annotation": {"query": "S-1"}})", "application/json");
  ASSERT_TRUE(ann);
  ASSERT_EQ(ann->status, 200) << ann->body;
  int detected = 0;
  for (const auto& o : runs) detected += o.analysis["detection"]["detected"].get<bool>();
  EXPECT_EQ(nlohmann::json::parse(ann->body).size(), static_cast<size_t>(detected));
}

}  // namespace
}  // namespace ambdiag::testing
