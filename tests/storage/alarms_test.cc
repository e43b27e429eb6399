// Alarms in the historian (schema v6): one open alarm per pump and rule, an
// append-only journal whose seq only grows, rule versions, the evaluation
// cursor, all kept across a reopen.
#include <gtest/gtest.h>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"
#include "sqlite_raw.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

using ambdiag::testing::alarm_event;
using ambdiag::testing::open_alarm;

class HistorianAlarmsTest : public ambdiag::testing::BackendTest {};
AMBDIAG_ON_BOTH_BACKENDS(HistorianAlarmsTest);

// Raises `rule` on `pump`: the new alarm and its journal entry.
std::int64_t raise(Historian& h, const std::string& pump, const std::string& rule) {
  AlarmChanges c;
  c.pump_id = pump;
  c.alarms.push_back(open_alarm(pump, rule));
  c.events.emplace_back(0, alarm_event("raise", "normal", "unack_active"));
  c.memories.emplace_back(rule, R"({"window":"1","clear_runs":0})");
  h.apply_alarm_changes(c);
  EXPECT_GT(c.alarms[0].alarm_id, 0);
  EXPECT_GT(c.events[0].second.seq, 0);
  EXPECT_EQ(c.events[0].second.alarm_id, c.alarms[0].alarm_id);
  return c.alarms[0].alarm_id;
}

TEST_P(HistorianAlarmsTest, OneOpenAlarmPerPumpAndRule) {
  const auto path = location();
  auto h = Historian::open(path);
  const auto id = raise(h, "P-1", "detection");
  raise(h, "P-2", "detection");       // another pump
  raise(h, "P-1", "poor_data");       // another rule
  const auto seq_before = h.last_alarm_seq();
  EXPECT_THROW(raise(h, "P-1", "detection"), InputError);
  EXPECT_EQ(h.last_alarm_seq(), seq_before) << "nothing of the refused change stored";
  EXPECT_EQ(h.open_alarms("P-1").size(), 2u);
  // Once closed (normal), the next raise is a new alarm.
  auto a = *h.find_alarm(id);
  a.state = "normal";
  a.active = false;
  a.acknowledged = true;
  a.cleared_at = "2026-11-26T11:00:00.000Z";
  AlarmChanges close;
  close.pump_id = "P-1";
  close.alarms.push_back(a);
  close.events.emplace_back(0, alarm_event("clear", "ack_active", "normal"));
  h.apply_alarm_changes(close);
  const auto second = raise(h, "P-1", "detection");
  EXPECT_GT(second, id);
  EXPECT_EQ(h.alarm_history(id).size(), 2u);
  EXPECT_EQ(h.alarm_history(second).size(), 1u);
  // Filters, newest first.
  AlarmFilter f;
  f.pump_id = "P-1";
  const auto list = h.list_alarms(f);
  ASSERT_EQ(list.size(), 3u);
  EXPECT_EQ(list.front().alarm_id, second);
  f.active = false;
  ASSERT_EQ(h.list_alarms(f).size(), 1u);
  EXPECT_EQ(h.list_alarms(f)[0].state, "normal");
  EXPECT_EQ(h.list_alarms(f)[0].cleared_at, "2026-11-26T11:00:00.000Z");
  f = {};
  f.state = "unack_active";
  EXPECT_EQ(h.list_alarms(f).size(), 3u);
}

TEST_P(HistorianAlarmsTest, JournalIsAppendOnlyWithAGrowingSeq) {
  const auto path = location();
  {
    auto h = Historian::open(path);
    raise(h, "P-1", "detection");
    raise(h, "P-2", "detection");
    raise(h, "P-3", "detection");
  }
  EXPECT_NE(raw_error(path, "UPDATE alarm_events SET by = 'mallory'"), "");
  EXPECT_NE(raw_error(path, "DELETE FROM alarm_events"), "");
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM alarm_events"), 3);
  auto h = Historian::open(path);  // kept across a reopen
  const auto all = h.alarm_events(0, 100);
  ASSERT_EQ(all.size(), 3u);
  for (size_t i = 1; i < all.size(); ++i) EXPECT_GT(all[i].seq, all[i - 1].seq);
  EXPECT_EQ(all[0].pump_id, "P-1");
  EXPECT_EQ(all[0].by, "server");
  // The cursor: after a seq, at most limit.
  const auto after = h.alarm_events(all[0].seq, 1);
  ASSERT_EQ(after.size(), 1u);
  EXPECT_EQ(after[0].seq, all[1].seq);
  EXPECT_TRUE(h.alarm_events(all[2].seq, 10).empty());
  EXPECT_EQ(h.alarm_events_between("2026-11-26T00:00:00.000Z", "2026-11-27T00:00:00.000Z").size(), 3u);
  EXPECT_TRUE(h.alarm_events_between("2026-11-27T00:00:00.000Z", "2026-11-28T00:00:00.000Z").empty());
  // A rolled-back change does not reuse its seq.
  EXPECT_THROW(raise(h, "P-1", "detection"), InputError);
  const auto next = raise(h, "P-4", "detection");
  EXPECT_GT(h.alarm_history(next).front().seq, all[2].seq);
}

TEST_P(HistorianAlarmsTest, RulesVersionsMemoriesAndCursorPersist) {
  const auto path = location();
  {
    auto h = Historian::open(path);
    EXPECT_FALSE(h.find_alarm_rules("P-1"));
    EXPECT_EQ(h.put_alarm_rules("P-1", R"({"rules":[]})", "eng"), 1);
    EXPECT_EQ(h.put_alarm_rules("P-1", R"({"rules":[{"id":"detection"}]})", "eng2"), 2);
    raise(h, "P-1", "detection");
    AlarmChanges c;
    c.pump_id = "P-1";
    c.cursor = AlarmCursor{"P-1", "2026-11-26T10:00:00Z", "P-1/r1", 1, 0, "2026-11-26T10:00:01.000Z"};
    h.apply_alarm_changes(c);
  }
  auto h = Historian::open(path, Historian::Mode::read);
  const auto rules = h.find_alarm_rules("P-1");
  ASSERT_TRUE(rules);
  EXPECT_EQ(rules->version, 2);
  EXPECT_EQ(rules->created_by, "eng2");
  ASSERT_EQ(h.alarm_memories("P-1").size(), 1u);
  EXPECT_EQ(h.alarm_memories("P-1")[0].first, "detection");
  const auto cur = h.find_alarm_cursor("P-1");
  ASSERT_TRUE(cur);
  EXPECT_EQ(cur->run_id, "P-1/r1");
  EXPECT_EQ(cur->last_valid_at, "2026-11-26T10:00:01.000Z");
  EXPECT_EQ(h.list_alarm_cursors().size(), 1u);
  const auto a = h.open_alarms("P-1").at(0);
  EXPECT_EQ(a.fault, "balance_piston_wear");
  EXPECT_DOUBLE_EQ(a.value.value_or(0), 1.7);
}

TEST_P(HistorianAlarmsTest, ExpiredShelvesAreFoundByTime) {
  auto h = Historian::open(location());
  const auto id = raise(h, "P-1", "detection");
  auto a = *h.find_alarm(id);
  a.state = "shelved";
  a.shelved_until = "2026-11-26T10:30:00.000Z";
  AlarmChanges c;
  c.pump_id = "P-1";
  c.alarms.push_back(a);
  c.events.emplace_back(0, alarm_event("shelve", "unack_active", "shelved", "ops"));
  h.apply_alarm_changes(c);
  EXPECT_TRUE(h.expired_shelves("2026-11-26T10:29:59.999Z").empty());
  ASSERT_EQ(h.expired_shelves("2026-11-26T10:30:00.000Z").size(), 1u);
}

}  // namespace
}  // namespace ambdiag::storage
