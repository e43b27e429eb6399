// Alarm rules: the defaults are valid, a pump's rules override them rule by
// rule, and bad rules are refused with the field named.
#include "alarms/alarm_rules.h"

#include <gtest/gtest.h>

#include "alarms/alarm_state.h"
#include "ambdiag/core/error.h"
#include "ambdiag/server/analysis_service.h"

namespace ambdiag::server::detail {
namespace {

using nlohmann::json;

std::string error_of(const json& overrides) {
  try {
    merge_rule_sets(default_rule_set_json(), overrides, "");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(AlarmRules, DefaultsHoldEveryRuleRestMdNames) {
  const AlarmRuleSet s = rule_set_from_json(default_rule_set_json(), "defaults");
  for (const char* id : {"detection", "fault.balance_piston_wear", "orbit_zone", "stale_data", "poor_data"})
    EXPECT_NE(s.find(id), nullptr) << id;
  ASSERT_NE(s.find("mode.radial bending 1 (forward).f_hz"), nullptr);
  EXPECT_EQ(s.find("mode.radial bending 1 (forward).f_hz")->id, "mode.*.f_hz");
  EXPECT_EQ(s.find("mode.x.zeta")->id, "mode.*.zeta");
  EXPECT_DOUBLE_EQ(s.speed_band, 0.05);
  const AlarmRule* piston = s.find("fault.balance_piston_wear");
  ASSERT_EQ(piston->levels.size(), 4u);
  EXPECT_EQ(piston->levels[3].severity, Severity::critical);
  EXPECT_DOUBLE_EQ(piston->levels[3].raise, 2.0);
  EXPECT_EQ(piston->latch, Severity::critical);
  // The JSON round trip gives the same set.
  EXPECT_EQ(rule_set_from_json(s.to_json(), "").to_json(), s.to_json());
}

TEST(AlarmRules, APumpRuleReplacesOnlyTheKeysItGives) {
  const AlarmRuleSet s = merge_rule_sets(default_rule_set_json(),
                                         {{"rules", {{{"id", "detection"}, {"on_delay", {{"k", 3}, {"n", 5}}}}}},
                                          {"plant_state", {{"speed_band", 0.08}}}},
                                         "");
  EXPECT_EQ(s.find("detection")->on_k, 3);
  EXPECT_EQ(s.find("detection")->on_n, 5);
  EXPECT_DOUBLE_EQ(s.find("detection")->clear, 0.8);  // the default's
  EXPECT_DOUBLE_EQ(s.speed_band, 0.08);
  EXPECT_NE(s.find("poor_data"), nullptr);  // not named: kept
}

TEST(AlarmRules, BadRulesAreRefusedNamingTheField) {
  EXPECT_EQ(error_of({{"rules", {{{"id", "detection"}}, {{"id", "poor_data"}}, {{"id", "stale_data"}, {"on_delay", {{"k", 3}, {"n", 2}}}}}}}),
            "rules[2].on_delay.k: must be <= n (2)");
  EXPECT_NE(error_of({{"rules", {{{"id", "detection"}, {"clear", 1.5}}}}}).find("rules[0].clear"), std::string::npos);
  EXPECT_NE(error_of({{"rules", {{{"id", "nonsense"}}}}}).find("rules[0].id: unknown rule"), std::string::npos);
  EXPECT_NE(error_of({{"rules", {{{"id", "detection"}, {"levels", {{{"severity", "huge"}, {"raise", 1}}}}}}}}).find("rules[0].levels[0].severity"),
            std::string::npos);
  EXPECT_NE(error_of({{"rules", {{{"id", "detection"}, {"levels", {{{"severity", "high"}, {"raise", 2}}, {{"severity", "critical"}, {"raise", 1}}}}}}}})
                .find("rules[0].levels[1].raise"),
            std::string::npos);
  EXPECT_NE(error_of({{"rules", {{{"id", "detection"}, {"clearance_m", 1e-4}}}}}).find("rules[0].clearance_m: unknown key"), std::string::npos);
  EXPECT_NE(error_of({{"rules", {{{"id", "fault.new_fault"}, {"levels", {{{"severity", "low"}, {"raise", 1}}}}, {"clear", 0.5}}}}})
                .find("rules[0].parameter"),
            std::string::npos);
  EXPECT_NE(error_of({{"rules", {{{"id", "orbit_zone"}, {"clearance_m", -1}}}}}).find("rules[0].clearance_m"), std::string::npos);
  EXPECT_NE(error_of({{"rules", {{{"id", "detection"}}, {{"id", "detection"}}}}}).find("rules[1].id: 'detection' given twice"), std::string::npos);
  EXPECT_NE(error_of({{"plant_state", {{"speed_band", 2}}}}).find("plant_state.speed_band"), std::string::npos);
  EXPECT_NE(error_of({{"plant_state", {{"band", 0.1}}}}).find("plant_state.band: unknown key"), std::string::npos);
  EXPECT_NE(error_of({{"rulez", json::array()}}).find("rulez: unknown key"), std::string::npos);
  EXPECT_NE(error_of(json::array()).find("must be an object"), std::string::npos);
  EXPECT_NE(error_of({{"rules", {{{"id", "detection"}, {"off_delay", 0}}}}}).find("rules[0].off_delay"), std::string::npos);
}

TEST(AlarmRules, ANewFaultRuleIsAccepted) {
  const AlarmRuleSet s = merge_rule_sets(default_rule_set_json(),
                                         {{"rules",
                                           {{{"id", "fault.rotor_crack"}, {"levels", {{{"severity", "critical"}, {"raise", 0.95}}}}, {"clear", 0.98}}}}},
                                         "");
  EXPECT_TRUE(s.find("fault.rotor_crack")->below);  // the default's direction
  EXPECT_EQ(s.find("fault.rotor_crack")->levels.size(), 1u);
}

storage::AlarmRecord raised() {
  storage::AlarmRecord a;
  a.alarm_id = 7;
  a.active = true;
  a.state = alarm_state_of(a);
  return a;
}

TEST(AlarmState, AckShelveAndUnshelveFollowIsa182) {
  auto a = raised();
  EXPECT_EQ(a.state, "unack_active");
  const AlarmActor op{"ops", "2026-11-26T10:00:00.000Z", "looking", ""};
  auto e = shelve_alarm(a, 30, op);
  EXPECT_EQ(e.from, "unack_active");
  EXPECT_EQ(e.to, "shelved");
  EXPECT_EQ(a.shelved_until, "2026-11-26T10:30:00.000Z");
  EXPECT_THROW(acknowledge_alarm(a, op), ConflictError);
  EXPECT_THROW(shelve_alarm(a, 30, op), ConflictError);
  e = expire_shelve(a, op);
  EXPECT_EQ(e.by, "server");
  EXPECT_EQ(a.state, "unack_active");
  e = acknowledge_alarm(a, op);
  EXPECT_EQ(e.to, "ack_active");
  EXPECT_EQ(e.by, "ops");
  EXPECT_THROW(acknowledge_alarm(a, op), ConflictError);
  EXPECT_THROW(unshelve_alarm(a, op), ConflictError);
  EXPECT_THROW(reset_alarm(a, true, op), ConflictError) << "not latched";
  change_alarm(a, "clear", op, [](storage::AlarmRecord& x) { x.active = false; });
  EXPECT_EQ(a.state, "normal");
  EXPECT_EQ(a.cleared_at, op.time);
  EXPECT_THROW(acknowledge_alarm(a, op), ConflictError) << "409: a normal alarm";
}

TEST(AlarmState, ShelveNeedsACommentAndMinutesInRange) {
  auto a = raised();
  EXPECT_THROW(shelve_alarm(a, 30, {"ops", "2026-11-26T10:00:00.000Z", " ", ""}), InputError);
  EXPECT_THROW(shelve_alarm(a, 0, {"ops", "2026-11-26T10:00:00.000Z", "why", ""}), InputError);
  EXPECT_THROW(shelve_alarm(a, 43201, {"ops", "2026-11-26T10:00:00.000Z", "why", ""}), InputError);
  EXPECT_EQ(a.state, "unack_active");  // nothing changed
}

TEST(AlarmState, TimesHaveThreeDecimalsSoTheySortAsText) {
  EXPECT_EQ(iso_ms(0), "1970-01-01T00:00:00.000Z");
  EXPECT_EQ(iso_ms(1'500'000'000LL), "1970-01-01T00:00:01.500Z");
  EXPECT_LT(iso_ms(999'000'000LL), iso_ms(1'000'000'000LL));
}

}  // namespace
}  // namespace ambdiag::server::detail
