// The alarm engine on its own: on-delay, hysteresis, off-delay, latching,
// suppression, missing data, and that a value around its limit does not
// chatter (transitions counted).
#include "alarms/alarm_engine.h"

#include <cmath>

#include <gtest/gtest.h>

#include "alarms/alarm_state.h"
#include "ambdiag/core/error.h"

namespace ambdiag::server::detail {
namespace {

using nlohmann::json;

// The built-in rules with one rule changed.
AlarmRuleSet rules_with(const json& rule) { return merge_rule_sets(default_rule_set_json(), {{"rules", {rule}}}, "test"); }

AlarmRuleSet detection_rules(int k, int n, int off, double clear, std::optional<std::string> latch = std::nullopt) {
  json r = {{"id", "detection"}, {"on_delay", {{"k", k}, {"n", n}}}, {"off_delay", off}, {"clear", clear},
            {"levels", {{{"severity", "medium"}, {"raise", 1.0}}, {{"severity", "critical"}, {"raise", 3.0}}}}};
  if (latch) r["latch"] = *latch;
  return rules_with(r);
}

// A run with a reference whose detection ratio is `ratio`.
RunFacts run_with_ratio(int i, double ratio, double speed_rpm = 2950.0) {
  RunFacts f;
  f.pump_id = "P-1";
  f.run_id = "P-1/run-" + std::to_string(i);
  f.time = iso_ms(1'790'000'000'000'000'000LL + i * 3'600'000'000'000LL);
  f.speed_rpm = speed_rpm;
  f.model_speed_rpm = 2950.0;
  f.has_detection = true;
  f.detected = ratio >= 1.0;
  f.values = {{"detection.ratio", "1", ratio, std::nullopt}, {"fit.nrmse", "1", 0.02, std::nullopt}};
  return f;
}

// Feeds the runs, storing nothing but keeping the pump's state as storage
// would (new alarms get ids); returns the journal.
struct Feed {
  explicit Feed(AlarmRuleSet r) : rules(std::move(r)) {}
  AlarmRuleSet rules;
  PumpAlarms pump;
  std::vector<storage::AlarmEvent> journal;
  std::int64_t next_id = 1;

  void run(const RunFacts& f) { store(evaluate_run(rules, pump, f)); }
  void store(storage::AlarmChanges c) {
    for (auto& a : c.alarms)
      if (a.alarm_id == 0) {
        a.alarm_id = next_id++;
        if (pump.open.contains(a.rule) && pump.open[a.rule].alarm_id == 0) pump.open[a.rule].alarm_id = a.alarm_id;
      }
    for (auto& [i, e] : c.events) {
      e.alarm_id = c.alarms[i].alarm_id;
      e.rule = c.alarms[i].rule;
      journal.push_back(e);
    }
  }
  int count(const std::string& rule, const std::string& kind) const {
    int n = 0;
    for (const auto& e : journal) n += e.rule == rule && e.kind == kind ? 1 : 0;
    return n;
  }
  const storage::AlarmRecord* open(const std::string& rule) const {
    const auto it = pump.open.find(rule);
    return it == pump.open.end() ? nullptr : &it->second;
  }
};

TEST(AlarmEngine, OnDelayRaisesAfterKOfTheLastNRuns) {
  Feed feed{detection_rules(2, 3, 2, 0.8)};
  feed.run(run_with_ratio(0, 1.5));
  EXPECT_EQ(feed.open("detection"), nullptr) << "one of three is not enough";
  feed.run(run_with_ratio(1, 0.5));
  EXPECT_EQ(feed.open("detection"), nullptr);
  feed.run(run_with_ratio(2, 1.2));  // 1, 0, 1: two of the last three
  ASSERT_NE(feed.open("detection"), nullptr);
  EXPECT_EQ(feed.open("detection")->state, "unack_active");
  EXPECT_EQ(feed.open("detection")->run_id, "P-1/run-2");
  EXPECT_EQ(feed.open("detection")->severity, "medium");
  EXPECT_EQ(feed.count("detection", "raise"), 1);
  EXPECT_EQ(feed.journal.front().by, "server");
  EXPECT_EQ(feed.journal.front().from, "normal");
}

TEST(AlarmEngine, AnIsolatedExceedanceOutsideTheWindowDoesNotRaise) {
  Feed feed{detection_rules(2, 3, 2, 0.8)};
  for (int i = 0; i < 20; ++i) feed.run(run_with_ratio(i, i % 3 == 0 ? 1.5 : 0.3));  // 1 in 3, never 2 of 3
  EXPECT_EQ(feed.count("detection", "raise"), 0);
}

TEST(AlarmEngine, AValueOscillatingAroundTheLimitDoesNotChatter) {
  // 0.95, 1.05, 0.95, ...: without hysteresis and delays it would raise
  // and clear on every other run (10 raises in 20 runs).
  Feed feed{detection_rules(2, 3, 2, 0.8)};
  for (int i = 0; i < 20; ++i) feed.run(run_with_ratio(i, i % 2 == 0 ? 0.95 : 1.05));
  EXPECT_EQ(feed.count("detection", "raise"), 1);
  EXPECT_EQ(feed.count("detection", "clear"), 0) << "0.95 is above the clear limit 0.8";
  // The same alarm was updated by every later run, no second one.
  EXPECT_EQ(feed.open("detection")->run_id, "P-1/run-19");
  // Below the clear limit for the off-delay (2 runs): it returns, once.
  feed.run(run_with_ratio(20, 0.5));
  EXPECT_TRUE(feed.open("detection")->active);
  feed.run(run_with_ratio(21, 0.5));
  EXPECT_FALSE(feed.open("detection")->active);
  EXPECT_EQ(feed.open("detection")->state, "unack_rtn");
  EXPECT_EQ(feed.count("detection", "clear"), 1);
  // Counted over the whole sequence: two transitions, where a plain limit gives 21.
  EXPECT_EQ(feed.journal.size(), 2u);
}

TEST(AlarmEngine, OffDelayNeedsConsecutiveRunsBeyondTheClearLimit) {
  Feed feed{detection_rules(1, 1, 3, 0.8)};
  feed.run(run_with_ratio(0, 2.0));
  ASSERT_TRUE(feed.open("detection")->active);
  feed.run(run_with_ratio(1, 0.5));
  feed.run(run_with_ratio(2, 0.5));
  feed.run(run_with_ratio(3, 0.9));  // in the hysteresis band: the count starts again
  feed.run(run_with_ratio(4, 0.5));
  feed.run(run_with_ratio(5, 0.5));
  EXPECT_TRUE(feed.open("detection")->active);
  feed.run(run_with_ratio(6, 0.5));
  EXPECT_FALSE(feed.open("detection")->active);
}

TEST(AlarmEngine, AcknowledgedAlarmThatReturnsIsClosedAndTheNextRaiseIsANewAlarm) {
  Feed feed{detection_rules(1, 1, 1, 0.8)};
  feed.run(run_with_ratio(0, 2.0));
  auto& a = feed.pump.open.at("detection");
  const auto first_id = a.alarm_id;
  acknowledge_alarm(a, {"op", iso_ms(0), "seen", ""});
  EXPECT_EQ(a.state, "ack_active");
  feed.run(run_with_ratio(1, 0.2));
  EXPECT_EQ(feed.open("detection"), nullptr) << "returned and acknowledged: normal, closed";
  feed.run(run_with_ratio(2, 2.0));
  ASSERT_NE(feed.open("detection"), nullptr);
  EXPECT_EQ(feed.open("detection")->alarm_id, first_id + 1);
}

TEST(AlarmEngine, UnacknowledgedReturnedAlarmComesBackAsTheSameAlarm) {
  Feed feed{detection_rules(1, 1, 1, 0.8)};
  feed.run(run_with_ratio(0, 2.0));
  const auto id = feed.open("detection")->alarm_id;
  feed.run(run_with_ratio(1, 0.2));
  EXPECT_EQ(feed.open("detection")->state, "unack_rtn");
  feed.run(run_with_ratio(2, 2.0));
  EXPECT_EQ(feed.open("detection")->state, "unack_active");
  EXPECT_EQ(feed.open("detection")->alarm_id, id);
}

TEST(AlarmEngine, SeverityEscalatesAndALatchedAlarmStaysUntilReset) {
  Feed feed{detection_rules(1, 1, 1, 0.8, "critical")};
  feed.run(run_with_ratio(0, 1.5));
  EXPECT_EQ(feed.open("detection")->severity, "medium");
  EXPECT_FALSE(feed.open("detection")->latched);
  feed.run(run_with_ratio(1, 4.0));
  EXPECT_EQ(feed.open("detection")->severity, "critical");
  EXPECT_TRUE(feed.open("detection")->latched);
  EXPECT_EQ(feed.count("detection", "update"), 1);
  for (int i = 2; i < 6; ++i) feed.run(run_with_ratio(i, 0.1));
  EXPECT_TRUE(feed.open("detection")->active) << "latched: stays active though clear";
  auto& a = feed.pump.open.at("detection");
  EXPECT_THROW(reset_alarm(a, true, {"eng", iso_ms(0), "", ""}), InputError) << "a comment is required";
  const auto e = reset_alarm(a, feed.pump.memory.at("detection").clear_runs >= 1, {"eng", iso_ms(0), "piston renewed", ""});
  EXPECT_EQ(e.kind, "reset");
  EXPECT_EQ(e.by, "eng");
  EXPECT_FALSE(a.active);
  EXPECT_EQ(a.state, "unack_rtn");
}

TEST(AlarmEngine, MissingDataNeverClearsAFaultAlarm) {
  Feed feed{rules_with({{"id", "fault.balance_piston_wear"}, {"off_delay", 1}})};
  RunFacts worn = run_with_ratio(0, 5.0);
  worn.best_fault = "balance_piston_wear";
  worn.values.push_back({"fault.balance_piston_wear.clearance_factor", "1", 1.7, 0.02});
  feed.run(worn);
  ASSERT_NE(feed.open("fault.balance_piston_wear"), nullptr);
  EXPECT_EQ(feed.open("fault.balance_piston_wear")->severity, "high");
  EXPECT_EQ(feed.open("fault.balance_piston_wear")->fault, "balance_piston_wear");
  // A failed analysis, a run without detection, another fault named: no value.
  RunFacts failed = run_with_ratio(1, 0.0);
  failed.analysis_failed = true;
  failed.values.clear();
  feed.run(failed);
  RunFacts no_ref = run_with_ratio(2, 0.0);
  no_ref.has_detection = false;
  feed.run(no_ref);
  RunFacts other = run_with_ratio(3, 5.0);
  other.best_fault = "rotor_crack";
  feed.run(other);
  EXPECT_TRUE(feed.open("fault.balance_piston_wear")->active);
  EXPECT_EQ(feed.count("fault.balance_piston_wear", "clear"), 0);
  // A failed analysis is poor data (on-delay 2 of 3: one is not enough).
  EXPECT_EQ(feed.open("poor_data"), nullptr);
}

TEST(AlarmEngine, AnAnalysisAlarmCarriesTheFaultItsRunWasDiagnosedWith) {
  Feed feed{detection_rules(1, 1, 1, 0.8)};
  RunFacts f = run_with_ratio(0, 3.0);
  f.best_fault = "dry_run";
  feed.run(f);
  EXPECT_EQ(feed.open("detection")->fault, "dry_run");
  Feed unknown{detection_rules(1, 1, 1, 0.8)};
  f.best_fault = "unknown";  // nothing explains the change
  unknown.run(f);
  EXPECT_FALSE(unknown.open("detection")->fault);
}

TEST(AlarmEngine, TheDefaultDetectionRuleWantsThreeRunsInARow) {
  Feed feed{rule_set_from_json(default_rule_set_json(), "")};
  feed.run(run_with_ratio(0, 1.5));
  feed.run(run_with_ratio(1, 1.5));
  feed.run(run_with_ratio(2, 0.5));
  feed.run(run_with_ratio(3, 1.5));
  EXPECT_EQ(feed.open("detection"), nullptr) << "two of three is not enough";
  feed.run(run_with_ratio(4, 1.5));
  feed.run(run_with_ratio(5, 1.5));
  ASSERT_NE(feed.open("detection"), nullptr);
  EXPECT_EQ(feed.open("detection")->run_id, "P-1/run-5");
}

TEST(AlarmEngine, FaultSeverityFollowsTheParameterSize) {
  for (const auto& [factor, severity] :
       std::vector<std::pair<double, std::string>>{{1.15, "low"}, {1.35, "medium"}, {1.7, "high"}, {2.2, "critical"}}) {
    Feed feed{rules_with({{"id", "fault.balance_piston_wear"}})};
    RunFacts worn = run_with_ratio(0, 5.0);
    worn.best_fault = "balance_piston_wear";
    worn.values.push_back({"fault.balance_piston_wear.clearance_factor", "1", factor, std::nullopt});
    feed.run(worn);
    ASSERT_NE(feed.open("fault.balance_piston_wear"), nullptr) << factor;
    EXPECT_EQ(feed.open("fault.balance_piston_wear")->severity, severity) << factor;
    EXPECT_EQ(feed.open("fault.balance_piston_wear")->latched, severity == "critical");
  }
  Feed below{rules_with({{"id", "fault.balance_piston_wear"}})};
  RunFacts slight = run_with_ratio(0, 2.0);
  slight.best_fault = "balance_piston_wear";
  slight.values.push_back({"fault.balance_piston_wear.clearance_factor", "1", 1.05, std::nullopt});  // within the drift
  below.run(slight);
  EXPECT_EQ(below.open("fault.balance_piston_wear"), nullptr);
}

TEST(AlarmEngine, OffSpeedRunSuppressesAnalysisAlarmsWhileEvaluationGoesOn) {
  Feed feed{detection_rules(1, 1, 1, 0.8)};
  feed.run(run_with_ratio(0, 2.0, 2500.0));  // 15 % below the model's 2950 rpm
  ASSERT_NE(feed.open("detection"), nullptr);
  EXPECT_EQ(feed.open("detection")->state, "suppressed");
  EXPECT_TRUE(feed.open("detection")->active) << "evaluated all the same";
  EXPECT_NE(feed.open("detection")->suppressed_reason.find("outside the trusted band"), std::string::npos);
  feed.run(run_with_ratio(1, 2.0, 2960.0));  // back in the band, still detected
  EXPECT_EQ(feed.open("detection")->state, "unack_active");
  EXPECT_EQ(feed.count("detection", "release"), 1);
  // A variable-speed drive's few percent stay inside the default +-5 %.
  Feed vsd{detection_rules(1, 1, 1, 0.8)};
  vsd.run(run_with_ratio(0, 2.0, 2950.0 * 1.04));
  EXPECT_EQ(vsd.open("detection")->state, "unack_active");
  // A stopped pump.
  Feed stopped{detection_rules(1, 1, 1, 0.8)};
  stopped.run(run_with_ratio(0, 2.0, 0.0));
  EXPECT_NE(stopped.open("detection")->suppressed_reason.find("stopped"), std::string::npos);
}

TEST(AlarmEngine, ModeShiftBeyondTheReferenceScatterRaisesPerLabel) {
  Feed feed{rules_with({{"id", "mode.*.f_hz"}, {"on_delay", {{"k", 1}, {"n", 1}}}})};
  RunFacts f = run_with_ratio(0, 0.5);
  const std::string name = "mode.radial bending 1 (forward).f_hz";
  f.reference[name] = {200.0, 0.5, 3};
  f.values.push_back({name, "Hz", 206.0, 0.1});  // 3 %: inside max(5 %, 6 sd = 1.5 %)
  feed.run(f);
  EXPECT_EQ(feed.open(name), nullptr);
  f.values.back().value = 185.0;  // -7.5 %
  feed.run(f);
  ASSERT_NE(feed.open(name), nullptr);
  EXPECT_EQ(feed.open(name)->severity, "low");
  EXPECT_NE(feed.open(name)->message.find("-7.50 %"), std::string::npos) << feed.open(name)->message;
}

TEST(AlarmEngine, OrbitZonesAfterIso14839) {
  EXPECT_EQ(orbit_zone(0.1), 'A');
  EXPECT_EQ(orbit_zone(0.35), 'B');
  EXPECT_EQ(orbit_zone(0.45), 'C');
  EXPECT_EQ(orbit_zone(0.6), 'D');
  Feed feed{rules_with({{"id", "orbit_zone"}, {"clearance_m", 250e-6}})};
  RunFacts f = run_with_ratio(0, 0.2);
  f.displacement_m = 50e-6;  // zone A
  feed.run(f);
  EXPECT_EQ(feed.open("orbit_zone"), nullptr);
  f.displacement_m = 130e-6;  // 0.52: zone D
  feed.run(f);
  ASSERT_NE(feed.open("orbit_zone"), nullptr);
  EXPECT_EQ(feed.open("orbit_zone")->severity, "critical");
  EXPECT_NE(feed.open("orbit_zone")->message.find("zone D"), std::string::npos);
  // Without a clearance (rule or plant): not evaluated.
  Feed none{rule_set_from_json(default_rule_set_json(), "")};
  none.run(f);
  EXPECT_EQ(none.open("orbit_zone"), nullptr);
}

TEST(AlarmEngine, StaleDataRaisesOnTheClockAndReturnsWithTheNextValidRun) {
  Feed feed{rules_with({{"id", "stale_data"}, {"limit_s", 3600}})};
  feed.store(evaluate_stale(feed.rules, feed.pump, "P-1", 1800, iso_ms(0)));
  EXPECT_EQ(feed.open("stale_data"), nullptr);
  feed.store(evaluate_stale(feed.rules, feed.pump, "P-1", 7200, iso_ms(0)));
  ASSERT_NE(feed.open("stale_data"), nullptr);
  feed.store(evaluate_stale(feed.rules, feed.pump, "P-1", 9000, iso_ms(0)));
  EXPECT_EQ(feed.count("stale_data", "raise"), 1) << "one alarm while it lasts";
  feed.run(run_with_ratio(1, 0.3));
  EXPECT_FALSE(feed.open("stale_data")->active);
}

TEST(AlarmEngine, ADisabledRuleTakesItsAlarmOutOfService) {
  Feed feed{detection_rules(1, 1, 1, 0.8)};
  feed.run(run_with_ratio(0, 2.0));
  feed.rules = rules_with({{"id", "detection"}, {"enabled", false}});
  feed.run(run_with_ratio(1, 2.0));
  EXPECT_EQ(feed.open("detection")->state, "out_of_service");
  feed.rules = detection_rules(1, 1, 1, 0.8);
  feed.run(run_with_ratio(2, 2.0));
  EXPECT_EQ(feed.open("detection")->state, "unack_active");
}

}  // namespace
}  // namespace ambdiag::server::detail
