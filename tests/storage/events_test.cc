// The events table (schema v8): seqs that only grow, from the migration's
// time in microseconds; an event commits with what it announces or not at
// all (a WriteBatch); reading by seq from several connections; pruning.
#include <gtest/gtest.h>

#include <chrono>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

class EventsTest : public ambdiag::testing::BackendTest {};
AMBDIAG_ON_BOTH_BACKENDS(EventsTest);

std::int64_t now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

TEST_P(EventsTest, SeqsStartAtTheMigrationTimeAndGrowByOne) {
  const auto before = now_us();
  auto h = Historian::open(location());
  // PostgreSQL: with the table empty, last_event_seq is one less than the
  // sequence (an append may be in flight, historian_events.cc).
  const auto start = h.last_event_seq() + (postgres() ? 1 : 0);
  EXPECT_GE(start, before - 1000000);  // julianday's millisecond resolution, and a second of slack
  EXPECT_LE(start, now_us());
  EXPECT_FALSE(h.first_event_seq());
  EXPECT_TRUE(h.events_after(0, 10).empty());
  const auto a = h.append_event("model.new", "P-1", R"({"pump_id":"P-1","model_version":1})");
  const auto b = h.append_event("run.new", "P-2", R"({"run_id":"r"})");
  EXPECT_EQ(a, start + 1);
  EXPECT_EQ(b, a + 1);
  EXPECT_EQ(h.last_event_seq(), b);
  EXPECT_EQ(h.first_event_seq(), a);
  auto reader = Historian::open(location(), Historian::Mode::read);  // a REST process' tail
  const auto got = reader.events_after(a - 1, 10);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0].seq, a);
  EXPECT_EQ(got[0].type, "model.new");
  EXPECT_EQ(got[0].pump_id, "P-1");
  EXPECT_EQ(got[0].data_json, R"({"pump_id":"P-1","model_version":1})");
  EXPECT_EQ(got[1].type, "run.new");
  EXPECT_EQ(got[0].time.size(), 24u) << got[0].time;  // 2026-11-26T10:00:00.000Z
  EXPECT_EQ(reader.events_after(a, 10).size(), 1u);
  EXPECT_EQ(reader.recent_events(1).at(0).seq, b);
  EXPECT_EQ(reader.recent_events(5).size(), 2u);
  EXPECT_THROW(reader.events_after(0, 0), InputError);
  // A line break would forge a field of the event stream.
  EXPECT_THROW(h.append_event("x\nid: 1", "", "{}"), InputError);
  EXPECT_THROW(h.append_event("x", "", "{\n}"), InputError);
  EXPECT_EQ(h.last_event_seq(), b);
}

TEST_P(EventsTest, AnEventCommitsWithWhatItAnnouncesOrNotAtAll) {
  auto h = Historian::open(location());
  {
    auto batch = h.write_batch();
    h.put_model("P-1", "{}", "eng");
    h.append_event("model.new", "P-1", "{}");
    // destroyed without commit: neither the model nor its event
  }
  EXPECT_FALSE(h.find_model("P-1"));
  EXPECT_FALSE(h.first_event_seq());
  {
    auto batch = h.write_batch();
    h.put_model("P-1", "{}", "eng");
    h.append_event("model.new", "P-1", "{}");
    batch.commit();
  }
  EXPECT_TRUE(h.find_model("P-1"));
  ASSERT_EQ(h.recent_events(10).size(), 1u);
}

TEST_P(EventsTest, PruningKeepsTheNewestRowsAndNothingOlderThanTheCutoffAndTheSeqGoesOn) {
  auto h = Historian::open(location());
  {
    auto batch = h.write_batch();
    for (int i = 0; i < 50; ++i) h.append_event("x", "", "{\"n\":" + std::to_string(i) + "}");
    batch.commit();
  }
  const auto last = h.last_event_seq();
  EXPECT_EQ(h.prune_events(20, "2000-01-01T00:00:00.000Z"), 30);
  const auto kept = h.recent_events(100);
  ASSERT_EQ(kept.size(), 20u);
  EXPECT_EQ(kept.front().seq, last - 19);
  EXPECT_EQ(kept.back().seq, last);
  // Everything older than a cutoff in the future: the table is empty, the
  // sequence is not reset (a tail that starts from it misses nothing).
  EXPECT_EQ(h.prune_events(1000, "9999-01-01T00:00:00.000Z"), 20);
  EXPECT_FALSE(h.first_event_seq());
  EXPECT_EQ(h.last_event_seq(), postgres() ? last - 1 : last);
  EXPECT_EQ(h.append_event("x", "", "{}"), last + 1);
}

// append_event prunes by itself every kEventsPruneEvery seqs: rows older
// than kEventsKeep go without anyone calling prune_events.
TEST_P(EventsTest, AppendingKeepsTheTableBounded) {
  const auto path = location();
  auto h = Historian::open(path);
  h.append_event("x", "", "{}");
  ASSERT_EQ(raw_error(path, "UPDATE events SET time = '2000-01-01T00:00:00.000Z'"), "");  // a day and more ago
  {
    auto batch = h.write_batch();
    for (int i = 0; i < kEventsPruneEvery; ++i) h.append_event("x", "", "{}");
    batch.commit();
  }
  const auto first = h.first_event_seq();
  ASSERT_TRUE(first);
  EXPECT_GT(*first, h.last_event_seq() - kEventsPruneEvery) << "the old event was pruned";
}

}  // namespace
}  // namespace ambdiag::storage
