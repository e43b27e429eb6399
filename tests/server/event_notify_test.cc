// PostgreSQL's LISTEN/NOTIFY under the event tail (storage/event_listener.h,
// events/event_tail.h) on a schema of the test cluster: an append announces
// itself at its commit (and a rolled-back one does not), a tail whose poll
// period never comes gets events from another connection by notification,
// and after its connections were cut (as by a restart of PostgreSQL) it
// reconnects, LISTENs again and catches up by seq.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>

#include "ambdiag/storage/event_listener.h"
#include "ambdiag/storage/historian.h"
#include "events/event_tail.h"
#include "pg_cluster.h"
#include "test_support.h"

namespace ambdiag::server::detail {
namespace {

using namespace std::chrono_literals;
using storage::EventListener;
using storage::Historian;

std::optional<std::string> pg_location() { return ambdiag::testing::postgres_test_location(); }

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// The events a subscription gets until `n` arrived or `timeout` passed.
std::vector<Event> collect(EventBus::Subscription& sub, std::size_t n, std::chrono::milliseconds timeout) {
  std::vector<Event> got;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (got.size() < n && std::chrono::steady_clock::now() < deadline)
    for (auto& e : sub.wait(50ms)) got.push_back(std::move(e));
  return got;
}

TEST(EventNotify, NoListenerOnSqlite) {
  EXPECT_EQ(EventListener::open((ambdiag::testing::scratch_dir() / "h.db").string()), nullptr);
}

TEST(EventNotify, AnAppendIsAnnouncedAtItsCommitAndARolledBackOneIsNot) {
  const auto loc = pg_location();
  if (!loc) GTEST_SKIP() << "AMBDIAG_NO_POSTGRES=1";
  auto writer = Historian::open(*loc);
  auto listener = EventListener::open(*loc);
  ASSERT_NE(listener, nullptr);
  ASSERT_TRUE(listener->connected());
  {
    auto batch = writer.write_batch();
    writer.append_event("run.new", "P-1", "{}");
    EXPECT_FALSE(listener->wait(300ms)) << "announced before the commit";
    batch.commit();
  }
  EXPECT_TRUE(listener->wait(10s));
  EXPECT_EQ(listener->notifications(), 1);
  {
    auto batch = writer.write_batch();
    writer.append_event("run.new", "P-1", "{}");
  }  // rolled back
  EXPECT_FALSE(listener->wait(300ms)) << "a rolled-back append was announced";
  // Another schema's appends are on another channel.
  auto other = Historian::open(*pg_location());
  other.append_event("run.new", "P-9", "{}");
  EXPECT_FALSE(listener->wait(300ms)) << "woken by another schema's historian";
  EXPECT_EQ(listener->notifications(), 1);
}

TEST(EventNotify, TheTailGetsAnotherConnectionsEventsByNotificationAndAfterItsConnectionsWereCut) {
  const auto loc = pg_location();
  if (!loc) GTEST_SKIP() << "AMBDIAG_NO_POSTGRES=1";
  auto writer = Historian::open(*loc);
  // The tail's connections carry a name of their own, so that this test
  // cuts them and no other test's.
  const std::string app = "tail_" + std::to_string(::getpid());
  const std::string tail_loc = *loc + "&application_name=" + app;
  EventBus bus;
  EventTail tail(tail_loc, bus, 60s);  // the poll period alone would never come
  tail.start();
  auto sub = bus.subscribe(std::nullopt);

  auto t0 = std::chrono::steady_clock::now();
  const auto a = writer.append_event("job.done", "P-1", "{\"job_id\":1}");
  auto got = collect(*sub, 1, 20s);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].id, static_cast<std::uint64_t>(a));
  std::printf("commit -> bus by notification: %.1f ms\n", ms_since(t0));
  EXPECT_GE(tail.notifications(), 1);

  // As a restart of PostgreSQL does to them: both the tail's reader and its
  // listener lose their sessions. Events committed while they are away
  // come at the reconnect, the later ones by notification again.
  const auto cut = ambdiag::testing::pg_sql(
      *loc, "SELECT count(pg_terminate_backend(pid)) FROM pg_stat_activity WHERE application_name = '" + app + "'");
  EXPECT_EQ(cut, "2");
  std::vector<std::int64_t> seqs;
  for (int i = 0; i < 3; ++i) seqs.push_back(writer.append_event("run.new", "P-1", "{\"n\":" + std::to_string(i) + "}"));
  got = collect(*sub, 3, 20s);
  ASSERT_EQ(got.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(got[i].id, static_cast<std::uint64_t>(seqs[i]));
  t0 = std::chrono::steady_clock::now();
  const auto b = writer.append_event("alarm.transition", "P-2", "{\"seq\":1}");
  got = collect(*sub, 1, 20s);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].id, static_cast<std::uint64_t>(b));
  std::printf("after the reconnect, commit -> bus: %.1f ms\n", ms_since(t0));
  tail.stop();
}

}  // namespace
}  // namespace ambdiag::server::detail
