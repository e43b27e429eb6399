// EventBus: increasing ids, replay after a reconnect from the ring, the
// reload event when events are gone, and a slow subscriber that is dropped
// without ever holding up the publisher; stored events (the events table's
// seqs as ids) and a replay older than the ring from their history.
#include "ambdiag/server/events.h"

#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <stdexcept>
#include <thread>

namespace ambdiag::server {
namespace {

using namespace std::chrono_literals;

TEST(EventBus, SubscribersGetEventsInOrderWithIncreasingIds) {
  EventBus bus;
  auto sub = bus.subscribe(std::nullopt);
  const auto a = bus.publish("run.new", {{"run_id", "r1"}});
  const auto b = bus.publish("run.status", {{"run_id", "r1"}, {"status", "complete"}});
  EXPECT_EQ(b, a + 1);
  EXPECT_EQ(bus.last_id(), b);
  const auto got = sub->wait(1s);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0].id, a);
  EXPECT_EQ(got[0].type, "run.new");
  EXPECT_EQ(nlohmann::json::parse(got[1].data)["status"], "complete");
  EXPECT_EQ(sse_frame(got[0]),
            "id: " + std::to_string(a) + "\nevent: run.new\ndata: {\"run_id\":\"r1\"}\n\n");
  EXPECT_TRUE(sub->wait(20ms).empty());  // nothing more: the wait times out
  EXPECT_THROW(bus.publish("x\nid: 1", {}), std::logic_error);  // would forge a field line
  EXPECT_EQ(bus.last_id(), b);
}

TEST(EventBus, AReconnectingClientGetsWhatItMissedOrIsToldToReload) {
  EventBus bus(3);
  const auto first = bus.publish("x", {{"n", 1}});
  bus.publish("x", {{"n", 2}});
  bus.publish("x", {{"n", 3}});
  auto again = bus.subscribe(first);  // saw the first: gets 2 and 3
  auto got = again->wait(1s);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(nlohmann::json::parse(got[0].data)["n"], 2);
  bus.publish("x", {{"n", 4}});  // the ring (3) now holds 2..4: the first's successor is still there
  bus.publish("x", {{"n", 5}});  // now 3..5: event 2 is gone
  auto late = bus.subscribe(first);
  got = late->wait(1s);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].type, "reload");
  EXPECT_EQ(got[0].id, bus.last_id());
  EXPECT_EQ(nlohmann::json::parse(got[0].data)["last_event_id"], bus.last_id());
  // An id from another process (ahead of this bus) is told to reload too.
  auto future = bus.subscribe(bus.last_id() + 100);
  EXPECT_EQ(future->wait(1s).at(0).type, "reload");
  // Up to date: nothing replayed.
  auto current = bus.subscribe(bus.last_id());
  EXPECT_TRUE(current->wait(20ms).empty());
}

TEST(EventBus, ASlowSubscriberIsDroppedAndThePublisherNeverWaits) {
  EventBus bus;
  auto slow = bus.subscribe(std::nullopt, 8);  // never reads
  auto fast = bus.subscribe(std::nullopt, 100000);
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < 20000; ++i) bus.publish("x", {{"n", i}});
  const auto took = std::chrono::steady_clock::now() - t0;
  EXPECT_LT(took, 5s);  // bounded work per event, never a wait on a subscriber
  EXPECT_TRUE(slow->dropped());
  EXPECT_TRUE(slow->ended());
  EXPECT_TRUE(slow->wait(1s).empty());
  EXPECT_EQ(bus.dropped_total(), 1u);
  EXPECT_FALSE(fast->ended());
  EXPECT_EQ(fast->wait(1s).size(), 20000u);
}

TEST(EventBus, CloseWakesAWaitingSubscriberAndEndsIt) {
  EventBus bus;
  auto sub = bus.subscribe(std::nullopt);
  std::thread closer([&] {
    std::this_thread::sleep_for(50ms);
    bus.close();
  });
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_TRUE(sub->wait(10s).empty());
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 5s);
  EXPECT_TRUE(sub->ended());
  EXPECT_FALSE(sub->dropped());
  closer.join();
  EXPECT_EQ(bus.subscribers(), 1u);
  sub.reset();
  EXPECT_EQ(bus.subscribers(), 0u);
}

// What a tail publishes: events with the ids the table gave them, a ring
// of the newest, older ones read from the table on a reconnect; ids ahead
// of this bus (another server's tail was quicker) are not a reload.
TEST(EventBus, StoredEventsKeepTheirIdsAndOlderOnesComeFromTheHistory) {
  std::map<std::uint64_t, Event> table;  // the events table: seq -> event
  for (std::uint64_t seq = 101; seq <= 106; ++seq) table[seq] = {seq, "x", "{\"n\":" + std::to_string(seq) + "}"};
  EventBus bus(3);
  bus.start_at(100);  // the sequence before the first event
  bus.set_history([&](std::uint64_t after, std::size_t max) -> std::optional<std::vector<Event>> {
    if (after < 100 || after > table.rbegin()->first) return std::nullopt;  // not of this table
    std::vector<Event> out;
    for (auto it = table.upper_bound(after); it != table.end() && out.size() < max; ++it) out.push_back(it->second);
    return out;
  });
  for (std::uint64_t seq = 101; seq <= 104; ++seq) bus.publish_stored(table[seq]);
  bus.publish_stored(table[103]);  // read twice by the tail: ignored
  EXPECT_EQ(bus.last_id(), 104u);
  EXPECT_THROW(bus.start_at(7), std::logic_error);

  auto old = bus.subscribe(100);  // older than the ring (102..104): 101 from the history
  auto got = old->wait(1s);
  ASSERT_EQ(got.size(), 6u) << "the history also holds 105 and 106, not yet tailed";
  for (std::size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i].id, 101 + i);
  bus.publish_stored(table[105]);  // the tail catches up: not sent twice
  bus.publish_stored(table[106]);
  EXPECT_TRUE(old->wait(50ms).empty());
  table[107] = {107, "x", "{}"};
  bus.publish_stored(table[107]);
  ASSERT_EQ(old->wait(1s).at(0).id, 107u);

  auto ahead = bus.subscribe(107);  // up to date
  EXPECT_TRUE(ahead->wait(20ms).empty());
  auto foreign = bus.subscribe(99);  // before the table's first: gone
  EXPECT_EQ(foreign->wait(1s).at(0).type, "reload");
  auto future = bus.subscribe(5000);  // beyond the table's newest: another database
  EXPECT_EQ(future->wait(1s).at(0).type, "reload");
}

}  // namespace
}  // namespace ambdiag::server
