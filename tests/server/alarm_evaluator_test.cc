// The alarm evaluation on a real historian file: runs evaluated in run
// order when analyses finish out of order, an evaluation lost to a crash
// made at the next start, the first reference re-evaluating the runs after
// it, the clock's part (stale data, shelves that expire), and two servers
// evaluating one pump at once; on both backends.
#include "alarms/alarm_evaluator.h"

#include <gtest/gtest.h>

#include <atomic>
#include <barrier>
#include <set>
#include <thread>
#include <tuple>

#include "../storage/historian_fixture.h"
#include "alarms/alarm_state.h"
#include "ambdiag/core/io_util.h"
#include "test_support.h"

namespace ambdiag::server::detail {
namespace {

using nlohmann::json;
using storage::Historian;

const std::string kPump = "P-1";

std::string run_id(int i) { return kPump + "/run-" + std::to_string(i); }

class AlarmEvaluation : public ambdiag::testing::BackendTest {
 protected:
  void SetUp() override {
    BackendTest::SetUp();
    if (IsSkipped()) return;
    path_ = location();
    h_.emplace(Historian::open(path_));
    defaults_ = merged_rule_set_json(default_rule_set_json(), json::object(), "defaults");
    h_->put_model(kPump, read_file_bytes(ambdiag::testing::data_file("reference_pump/plant.json").string()), "eng");
  }

  // A complete identification run, hour i of the day.
  void add_run(int i) {
    auto j = json::parse(ambdiag::testing::identification_json_text(run_id(i), kPump));
    char t[32];
    std::snprintf(t, sizeof t, "2026-11-21T%02d:00:00Z", i);
    j["started_at"] = t;
    j["speed_rpm"] = 2950.0;
    h_->begin_run(storage::run_header_from_json(j.dump()));
    const auto bytes = ambdiag::testing::samples_bytes(300, 2, static_cast<unsigned>(i));
    h_->put_chunks(run_id(i), ambdiag::testing::cut_chunks(bytes, 2, 100));
    ASSERT_EQ(h_->end_run(run_id(i), 300, ambdiag::testing::checksum_of(bytes)).status, storage::RunStatus::complete);
  }

  // The run's analysis against (model 1, reference r), done with this result.
  void finish(int i, int r, const json& result) {
    h_->enqueue_job({"analysis", kPump, run_id(i), 1, r});
    const auto job = h_->claim_job("test", {"analysis"});
    ASSERT_TRUE(job);
    ASSERT_EQ(job->key.run_id, run_id(i));
    ASSERT_TRUE(h_->finish_job(job->job_id, job->attempts, result.dump()));
  }

  static json healthy() {
    return {{"speed_rpm", 2950.0}, {"nrmse", 0.02}, {"modes", json::array()},
            {"detection", {{"detected", false}, {"ratio", 0.3}}}, {"diagnosis", nullptr}};
  }
  static json worn(double clearance_factor) {
    json r = healthy();
    r["detection"] = {{"detected", true}, {"ratio", 4.0}};
    r["diagnosis"] = {{"faults", {{{"fault", "balance_piston_wear"}, {"parameters", {{"clearance_factor", clearance_factor}}}}}}};
    return r;
  }
  static json without_reference() {
    json r = healthy();
    r["detection"] = nullptr;
    return r;
  }

  std::vector<storage::AlarmRecord> alarms(const std::string& rule) {
    std::vector<storage::AlarmRecord> out;
    for (const auto& a : h_->list_alarms({}))
      if (a.rule == rule) out.push_back(a);
    return out;
  }

  std::string path_;
  std::optional<Historian> h_;
  json defaults_;
};
AMBDIAG_ON_BOTH_BACKENDS(AlarmEvaluation);

TEST_P(AlarmEvaluation, AnalysesFinishingOutOfOrderAreEvaluatedInRunOrder) {
  for (int i = 0; i < 5; ++i) add_run(i);
  h_->put_reference(kPump, {run_id(0), run_id(1)}, "eng");
  std::vector<json> seen;
  AlarmEvaluator ev(defaults_, [&](const json& e) { seen.push_back(e); });
  finish(0, 1, healthy());
  finish(1, 1, healthy());
  finish(4, 1, worn(1.7));  // the newest run's analysis ends first
  EXPECT_EQ(ev.catch_up(*h_, kPump), 2) << "runs 0 and 1; run 2 is not analysed yet";
  EXPECT_TRUE(alarms("fault.balance_piston_wear").empty());
  EXPECT_EQ(h_->find_alarm_cursor(kPump)->run_id, run_id(1));
  finish(2, 1, healthy());
  EXPECT_EQ(ev.catch_up(*h_, kPump), 1);
  finish(3, 1, healthy());
  EXPECT_EQ(ev.catch_up(*h_, kPump), 2) << "run 3, then run 4 that waited";
  const auto a = alarms("fault.balance_piston_wear");
  ASSERT_EQ(a.size(), 1u);
  EXPECT_EQ(a[0].run_id, run_id(4));
  EXPECT_EQ(a[0].severity, "high");
  EXPECT_EQ(a[0].state, "unack_active");
  ASSERT_EQ(seen.size(), 1u) << "the sink heard the raise";
  EXPECT_EQ(seen[0]["run_id"], run_id(4));
  EXPECT_EQ(seen[0]["to"], "unack_active");
  EXPECT_EQ(seen[0]["seq"], h_->last_alarm_seq());
  EXPECT_EQ(ev.catch_up(*h_, kPump), 0) << "nothing evaluated twice";
}

TEST_P(AlarmEvaluation, AnEvaluationLostToACrashIsMadeAtTheNextStart) {
  for (int i = 0; i < 3; ++i) add_run(i);
  h_->put_reference(kPump, {run_id(0), run_id(1)}, "eng");
  finish(0, 1, healthy());
  finish(1, 1, healthy());
  finish(2, 1, worn(2.1));  // committed, then the server died before evaluating
  h_.reset();
  h_.emplace(Historian::open(path_));
  AlarmEvaluator restarted(defaults_, nullptr);
  EXPECT_EQ(restarted.catch_up(*h_, kPump), 3);
  const auto a = alarms("fault.balance_piston_wear");
  ASSERT_EQ(a.size(), 1u);
  EXPECT_EQ(a[0].severity, "critical");
  EXPECT_TRUE(a[0].latched);
  EXPECT_EQ(h_->alarm_history(a[0].alarm_id).size(), 1u);
  AlarmEvaluator again(defaults_, nullptr);
  EXPECT_EQ(again.catch_up(*h_, kPump), 0);
  EXPECT_EQ(h_->alarm_history(a[0].alarm_id).size(), 1u);
}

TEST_P(AlarmEvaluation, TheFirstReferenceReevaluatesTheRunsAfterIt) {
  for (int i = 0; i < 4; ++i) add_run(i);
  AlarmEvaluator ev(defaults_, nullptr);
  for (int i = 0; i < 4; ++i) finish(i, 0, without_reference());
  EXPECT_EQ(ev.catch_up(*h_, kPump), 4);
  EXPECT_TRUE(h_->list_alarms({}).empty());
  // The reference: every run analysed again with detection; run 3 is worn.
  h_->put_reference(kPump, {run_id(0), run_id(1)}, "eng");
  finish(0, 1, healthy());
  finish(1, 1, healthy());
  finish(2, 1, healthy());
  finish(3, 1, worn(1.4));
  EXPECT_EQ(ev.catch_up(*h_, kPump), 2) << "runs 2 and 3, after the reference's newest run";
  const auto a = alarms("fault.balance_piston_wear");
  ASSERT_EQ(a.size(), 1u);
  EXPECT_EQ(a[0].run_id, run_id(3));
  EXPECT_EQ(a[0].severity, "medium");
  EXPECT_EQ(h_->find_alarm_cursor(kPump)->reference_version, 1);
}

TEST_P(AlarmEvaluation, TheClockRaisesStaleDataAndEndsShelves) {
  add_run(0);
  finish(0, 0, without_reference());
  AlarmEvaluator ev(defaults_, nullptr);
  ASSERT_EQ(ev.catch_up(*h_, kPump), 1);
  const std::int64_t now = now_ns();
  ev.tick(*h_, now + 3600'000'000'000LL, true);
  EXPECT_TRUE(alarms("stale_data").empty()) << "an hour is within the default 24 h";
  ev.tick(*h_, now + 25 * 3600'000'000'000LL, true);
  auto stale = alarms("stale_data");
  ASSERT_EQ(stale.size(), 1u);
  EXPECT_EQ(stale[0].severity, "low");
  // Shelved for 10 minutes; the tick after them unshelves it, by the server.
  auto a = stale[0];
  storage::AlarmChanges c;
  c.pump_id = kPump;
  c.events.emplace_back(0, shelve_alarm(a, 10, {"ops", iso_ms(now), "known outage", ""}));
  c.alarms.push_back(a);
  h_->apply_alarm_changes(c);
  ev.tick(*h_, now + 9 * 60'000'000'000LL, false);
  EXPECT_EQ(h_->find_alarm(a.alarm_id)->state, "shelved");
  ev.tick(*h_, now + 11 * 60'000'000'000LL, false);
  EXPECT_EQ(h_->find_alarm(a.alarm_id)->state, "unack_active");
  const auto history = h_->alarm_history(a.alarm_id);
  ASSERT_EQ(history.size(), 3u);
  EXPECT_EQ(history[1].by, "ops");
  EXPECT_EQ(history[2].kind, "shelve_expired");
  EXPECT_EQ(history[2].by, "server");
}

// Two servers (two connections, an evaluator each) catching up one pump at
// the same moments: they take turns on the pump's alarms
// (Historian::lock_pump_alarms), so each run is evaluated once and each
// transition journaled once; without the lock, on PostgreSQL, both read the
// same cursor and both journal the same raise or clear.
TEST_P(AlarmEvaluation, TwoServersEvaluatingOnePumpAtOnceJournalEachTransitionOnce) {
  constexpr int kRuns = 12;
  for (int i = 0; i < kRuns; ++i) add_run(i);
  h_->put_reference(kPump, {run_id(0), run_id(1)}, "eng");
  // Worn and healthy in turns from run 2: a raise, a clear, ... to journal.
  for (int i = 0; i < kRuns; ++i) finish(i, 1, i >= 2 && i % 2 == 0 ? worn(1.7) : healthy());
  std::barrier start(2);
  std::atomic<int> evaluated{0};
  std::vector<std::thread> servers;
  for (int s = 0; s < 2; ++s)
    servers.emplace_back([&] {
      auto h = Historian::open(path_);
      AlarmEvaluator ev(defaults_, nullptr);
      start.arrive_and_wait();
      try {
        evaluated += ev.catch_up(h, kPump);
      } catch (const std::exception& e) {
        ADD_FAILURE() << e.what();
      }
    });
  for (auto& t : servers) t.join();
  EXPECT_EQ(evaluated, kRuns) << "every run evaluated once between the two";
  EXPECT_EQ(h_->find_alarm_cursor(kPump)->run_id, run_id(kRuns - 1));
  std::set<std::tuple<std::int64_t, std::string, std::string>> seen;
  const auto journal = h_->alarm_events(0, 1000);
  for (const auto& e : journal)
    EXPECT_TRUE(seen.insert({e.alarm_id, e.run_id, e.to}).second)
        << "alarm " << e.alarm_id << " " << e.kind << " to " << e.to << " of " << e.run_id << " journaled twice";
  EXPECT_FALSE(journal.empty());
}

}  // namespace
}  // namespace ambdiag::server::detail
