// EventTail: the events table read by seq into a bus, as each REST process
// does; events appended by another connection (another process) arrive
// with their seqs as ids, the ring is primed from the table at start, and
// wake() polls at once.
#include "events/event_tail.h"

#include <gtest/gtest.h>

#include <chrono>

#include "ambdiag/storage/historian.h"
#include "test_support.h"

namespace ambdiag::server::detail {
namespace {

using namespace std::chrono_literals;
using storage::Historian;

TEST(EventTail, EventsOfAnotherConnectionArriveWithTheirSeqsAsIds) {
  const auto path = (ambdiag::testing::scratch_dir() / "h.db").string();
  auto writer = Historian::open(path);
  for (int i = 0; i < 5; ++i) writer.append_event("run.new", "P-1", "{\"n\":" + std::to_string(i) + "}");
  const auto last = writer.last_event_seq();
  EventBus bus;
  EventTail tail(path, bus, 20ms);
  tail.start(3);  // the ring: the newest three
  EXPECT_EQ(bus.last_id(), static_cast<std::uint64_t>(last));
  auto from_ring = bus.subscribe(last - 3);
  const auto primed = from_ring->wait(1s);
  ASSERT_EQ(primed.size(), 3u);
  EXPECT_EQ(primed.front().id, static_cast<std::uint64_t>(last - 2));
  EXPECT_EQ(primed.back().data, "{\"n\":4}");

  auto sub = bus.subscribe(std::nullopt);
  const auto a = writer.append_event("job.done", "P-1", "{\"job_id\":1}");
  const auto b = writer.append_event("alarm.transition", "P-2", "{\"seq\":1}");
  std::vector<Event> got;
  for (int i = 0; i < 100 && got.size() < 2; ++i)
    for (auto& e : sub->wait(100ms)) got.push_back(std::move(e));
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0].id, static_cast<std::uint64_t>(a));
  EXPECT_EQ(got[0].type, "job.done");
  EXPECT_EQ(got[1].id, static_cast<std::uint64_t>(b));
  EXPECT_EQ(got[1].data, "{\"seq\":1}");
  EXPECT_GT(tail.polls(), 0);
  tail.stop();
}

TEST(EventTail, WakePollsAtOnce) {
  const auto path = (ambdiag::testing::scratch_dir() / "h.db").string();
  auto writer = Historian::open(path);
  EventBus bus;
  EventTail tail(path, bus, 60s);  // the poll period alone would never come
  tail.start();
  auto sub = bus.subscribe(std::nullopt);
  const auto seq = writer.append_event("model.new", "P-1", "{}");
  const auto t0 = std::chrono::steady_clock::now();
  tail.wake();  // as a database notification would
  const auto got = sub->wait(5s);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].id, static_cast<std::uint64_t>(seq));
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 2s);
}

// Reconnecting with an id older than the ring: the events after it come
// from the table, until they are pruned (then a reload).
TEST(EventTail, AReconnectOlderThanTheRingIsServedFromTheTable) {
  const auto path = (ambdiag::testing::scratch_dir() / "h.db").string();
  auto writer = Historian::open(path);
  std::vector<std::int64_t> seqs;
  for (int i = 0; i < 6; ++i) seqs.push_back(writer.append_event("run.new", "P-1", "{\"n\":" + std::to_string(i) + "}"));
  EventBus bus(2);  // a ring of two
  ReaderPool pool(path, 2);
  bus.set_history(events_table_history(pool));
  EventTail tail(path, bus, 20ms);
  tail.start(2);
  auto old = bus.subscribe(seqs.front());  // saw the first: the next four from the table, the last from the ring
  const auto got = old->wait(1s);
  ASSERT_EQ(got.size(), 5u);
  for (std::size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i].id, static_cast<std::uint64_t>(seqs[i + 1]));
  EXPECT_EQ(got.front().data, "{\"n\":1}");
  EXPECT_EQ(bus.subscribe(seqs.back() + 1000)->wait(1s).at(0).type, "reload");  // beyond the sequence
  writer.prune_events(1, "2000-01-01T00:00:00.000Z");  // only the newest is left
  EXPECT_EQ(bus.subscribe(seqs.front())->wait(1s).at(0).type, "reload");
  EXPECT_EQ(bus.subscribe(seqs[4])->wait(1s).at(0).id, static_cast<std::uint64_t>(seqs[5]));  // the ring still holds it
}

}  // namespace
}  // namespace ambdiag::server::detail
