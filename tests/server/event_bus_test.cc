// EventBus: increasing ids, replay after a reconnect from the ring, the
// reload event when events are gone, and a slow subscriber that is dropped
// without ever holding up the publisher.
#include "ambdiag/server/events.h"

#include <gtest/gtest.h>

#include <chrono>
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

}  // namespace
}  // namespace ambdiag::server
