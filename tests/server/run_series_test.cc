// run_series: the values one analysis result gives its pump's trends.
#include "trends/run_series.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

namespace ambdiag::server::detail {
namespace {

using nlohmann::json;

const SeriesValue* find(const std::vector<SeriesValue>& v, const std::string& name) {
  for (const auto& s : v)
    if (s.name == name) return &s;
  return nullptr;
}

TEST(RunSeries, RunWithoutReferenceGivesSpeedFitAndLabelledModesOnly) {
  const json r = {{"speed_rpm", 2950.0},
                  {"nrmse", 0.04},
                  {"detection", nullptr},
                  {"diagnosis", nullptr},
                  {"modes",
                   {{{"f_hz", 41.5}, {"zeta", 0.12}, {"f_sd_hz", 0.2}, {"zeta_sd", 0.01}, {"label", "radial rigid 1 (forward)"}},
                    {{"f_hz", 300.0}, {"zeta", 0.02}}}}};  // unlabelled: no series
  const auto v = run_series(r);
  ASSERT_EQ(v.size(), 4u);
  EXPECT_TRUE(std::is_sorted(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.name < b.name; }));
  const auto* f = find(v, "mode.radial rigid 1 (forward).f_hz");
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(f->value, 41.5);
  EXPECT_EQ(f->unit, "Hz");
  ASSERT_TRUE(f->sd);
  EXPECT_EQ(*f->sd, 0.2);
  EXPECT_NE(find(v, "mode.radial rigid 1 (forward).zeta"), nullptr);
  EXPECT_EQ(find(v, "run.speed_rpm")->unit, "rpm");
  EXPECT_EQ(find(v, "fit.nrmse")->value, 0.04);
  EXPECT_EQ(find(v, "detection.ratio"), nullptr);
}

TEST(RunSeries, DetectionOperatingFactorsAndTheBestFaultsParameters) {
  const json r = {
      {"speed_rpm", 3000.0},
      {"nrmse", 0.1},
      {"detection",
       {{"ratio", 3.5},
        {"p_value", 1e-9},
        {"operating", {{"nuisance", {{{"link", "balance piston"}, {"log_factor", 0.1}, {"factor", 1.105}, {"sd", 0.02}}}}}}}},
      {"diagnosis",
       {{"faults",
         {{{"fault", "balance_piston_wear"},
           {"parameters", {{"clearance_factor", 1.8}, {"clearance_factor_sd", 0.05}, {"clearance_factor_ci95", {1.7, 1.9}}}}},
          {{"fault", "impeller_seal_wear"}, {"parameters", {{"clearance_factor", 1.2}}}}}}}}};
  const auto v = run_series(r);
  EXPECT_EQ(find(v, "detection.ratio")->value, 3.5);
  const auto* op = find(v, "operating.balance piston.factor");
  ASSERT_NE(op, nullptr);
  EXPECT_NEAR(*op->sd, 1.105 * 0.02, 1e-12);
  const auto* cf = find(v, "fault.balance_piston_wear.clearance_factor");
  ASSERT_NE(cf, nullptr);
  EXPECT_EQ(cf->value, 1.8);
  EXPECT_EQ(*cf->sd, 0.05);
  // Only the best-ranked fault trends; its sd and interval are not series.
  EXPECT_EQ(find(v, "fault.impeller_seal_wear.clearance_factor"), nullptr);
  EXPECT_EQ(find(v, "fault.balance_piston_wear.clearance_factor_sd"), nullptr);
  EXPECT_EQ(find(v, "fault.balance_piston_wear.clearance_factor_ci95"), nullptr);
}

TEST(RunSeries, NonFiniteAndMalformedEntriesAreSkippedNotInvented) {
  json r = {{"speed_rpm", "fast"},
            {"nrmse", std::numeric_limits<double>::quiet_NaN()},
            {"detection", {{"ratio", 2.0}, {"operating", {{"nuisance", {{{"factor", 1.0}}}}}}}},
            {"modes", {{{"label", 7}, {"f_hz", 1.0}}, {{"label", "m"}, {"f_hz", 10.0}, {"f_sd_hz", -1.0}}}},
            {"diagnosis", {{"faults", json::array()}}}};
  const auto v = run_series(r);
  ASSERT_EQ(v.size(), 2u);
  EXPECT_EQ(v[0].name, "detection.ratio");
  EXPECT_EQ(v[1].name, "mode.m.f_hz");
  EXPECT_FALSE(v[1].sd);  // a negative sd is not an sd
  EXPECT_TRUE(run_series(json::array({1, 2})).empty());
}

}  // namespace
}  // namespace ambdiag::server::detail
