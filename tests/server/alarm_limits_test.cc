// alarm_limits: a rule's levels and clear limit as lines in the unit of the
// series it watches, checked against the rule set they come from (the
// built-in defaults with overrides), so the test follows the rules.
#include "alarms/alarm_limits.h"

#include <gtest/gtest.h>

namespace ambdiag::server::detail {
namespace {

using nlohmann::json;

AlarmRuleSet rules(const json& overrides = json::object()) {
  return merge_rule_sets(default_rule_set_json(), overrides, "test rules");
}

std::vector<double> values(const json& limits, const std::string& kind) {
  std::vector<double> v;
  for (const auto& l : limits["lines"])
    if (l["kind"] == kind) v.push_back(l["value"].get<double>());
  return v;
}

TEST(AlarmLimits, DetectionRatioIsDrawnAtTheRulesLevelsAndClearLimit) {
  const AlarmRuleSet r = rules();
  const auto l = alarm_limits(r, "detection.ratio", std::nullopt);
  ASSERT_TRUE(l);
  EXPECT_EQ((*l)["rule"], "detection");
  const AlarmRule* d = r.find("detection");
  ASSERT_EQ(values(*l, "raise").size(), d->levels.size());
  for (size_t i = 0; i < d->levels.size(); ++i) {
    EXPECT_EQ(values(*l, "raise")[i], d->levels[i].raise);
    EXPECT_EQ((*l)["lines"][i]["severity"], to_string(d->levels[i].severity));
  }
  EXPECT_EQ(values(*l, "clear"), std::vector<double>{d->clear});
}

TEST(AlarmLimits, AFaultParameterOnlyOnTheSeriesOfTheParameterItsRuleCompares) {
  const AlarmRuleSet r = rules();
  const AlarmRule* f = r.find("fault.balance_piston_wear");
  ASSERT_NE(f, nullptr);
  const auto l = alarm_limits(r, "fault.balance_piston_wear." + f->parameter, std::nullopt);
  ASSERT_TRUE(l);
  EXPECT_EQ(values(*l, "raise").size(), f->levels.size());
  EXPECT_EQ(values(*l, "raise").back(), f->levels.back().raise);
  EXPECT_FALSE(alarm_limits(r, "fault.balance_piston_wear.not_its_parameter", std::nullopt));
  EXPECT_FALSE(alarm_limits(r, "fault.no_such_fault.x", std::nullopt));
}

TEST(AlarmLimits, ARuleAboutANominalValueIsDrawnOnBothSidesOfIt) {
  const AlarmRuleSet r = rules();
  const AlarmRule* g = r.find("fault.sensor_fault");
  ASSERT_NE(g, nullptr);
  ASSERT_TRUE(g->nominal);
  const auto l = alarm_limits(r, "fault.sensor_fault." + g->parameter, std::nullopt);
  ASSERT_TRUE(l);
  const auto raise = values(*l, "raise");
  ASSERT_EQ(raise.size(), 2 * g->levels.size());
  EXPECT_DOUBLE_EQ(raise[0], *g->nominal + g->levels[0].raise);
  EXPECT_DOUBLE_EQ(raise[1], *g->nominal - g->levels[0].raise);
}

TEST(AlarmLimits, AModesLimitsFollowTheReferenceBandAndNeedIt) {
  const AlarmRuleSet r = rules();
  const std::string series = "mode.radial bending 1 (forward).f_hz";
  const AlarmRule* m = r.find(series);
  ASSERT_NE(m, nullptr);
  EXPECT_FALSE(alarm_limits(r, series, std::nullopt));
  // A wide reference scatter: k_sd sd beyond the minimum shift sets the width.
  const double mean = 300.0, sd = 0.2 * m->min_relative_shift * mean;
  const auto l = alarm_limits(r, series, json{{"mean", mean}, {"sd", sd}});
  ASSERT_TRUE(l);
  const double width = std::max(m->min_relative_shift * mean, m->k_sd * sd);
  const auto raise = values(*l, "raise");
  ASSERT_EQ(raise.size(), 2 * m->levels.size());
  EXPECT_NEAR(raise[0], mean + m->levels[0].raise * width, 1e-9);
  EXPECT_NEAR(raise[1], mean - m->levels[0].raise * width, 1e-9);
}

TEST(AlarmLimits, NrmseIsDrawnInItsOwnUnitAndADisabledRuleOrAnUnwatchedSeriesDrawsNothing) {
  const AlarmRuleSet r = rules();
  const AlarmRule* p = r.find("poor_data");
  const auto l = alarm_limits(r, "fit.nrmse", std::nullopt);
  ASSERT_TRUE(l);
  EXPECT_DOUBLE_EQ(values(*l, "raise")[0], p->levels[0].raise * p->nrmse_limit);
  EXPECT_FALSE(alarm_limits(rules({{"rules", {{{"id", "detection"}, {"enabled", false}}}}}), "detection.ratio", std::nullopt));
  EXPECT_FALSE(alarm_limits(r, "run.speed_rpm", std::nullopt));
  EXPECT_FALSE(alarm_limits(r, "monitoring.orbit_major_m.a", std::nullopt));
}

}  // namespace
}  // namespace ambdiag::server::detail
