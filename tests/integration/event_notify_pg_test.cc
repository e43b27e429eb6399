// LISTEN/NOTIFY between real servers on one PostgreSQL database of the test
// cluster (docs/service.md "Several servers"): A writes, B streams with
// notifications, P streams with its poll alone (--bench-no-event-notify).
// Every event A commits reaches both streams, complete and in seq order;
// B's come by notification (its counter in /metrics), P's by its poll. The
// commit -> SSE latencies of both are printed (docs/benchmarks.md), not
// asserted: a loaded machine makes any bound flaky.
#include <algorithm>
#include <random>

#include "multi_server_fixture.h"

namespace ambdiag::testing {
namespace {

class EventNotifyPgTest : public MultiServerTest {
 protected:
  void SetUp() override {
    const auto loc = postgres_test_location();
    if (!loc) GTEST_SKIP() << "AMBDIAG_NO_POSTGRES=1: the PostgreSQL backend is not tested";
    db = *loc;
  }

  // A counter of the server's GET /metrics (no token needed), -1 if absent.
  double metric_on(const std::string& name, const std::string& metric) const {
    httplib::Client c("127.0.0.1", servers.at(name).port);
    const auto r = c.Get("/metrics");
    if (!r || r->status != 200) return -1;
    const auto at = r->body.find("\n" + metric + " ");
    return at == std::string::npos ? -1 : std::stod(r->body.substr(at + metric.size() + 2));
  }
};

// The events of `type` a stream saw, in arrival order.
std::vector<SeenEvent> of_type(EventStream& s, const std::string& type) {
  std::vector<SeenEvent> out;
  for (auto& e : s.events())
    if (e.type == type) out.push_back(e);
  return out;
}

void print_latencies(const char* what, std::vector<double> ms) {
  std::sort(ms.begin(), ms.end());
  if (ms.empty()) return;
  std::printf("%s: commit -> SSE over %zu events: median %.1f ms, p90 %.1f ms, max %.1f ms\n", what, ms.size(),
              ms[ms.size() / 2], ms[ms.size() * 9 / 10], ms.back());
}

TEST_F(EventNotifyPgTest, EventsCommittedOnOneServerReachTheStreamsOfAnotherInOrderByNotification) {
  make_tokens();
  start_part("A", "rest");
  start_part("B", "rest");
  start_part("P", "rest", {"--bench-no-event-notify"});
  ASSERT_FALSE(HasFailure()) << logs();
  EventStream on_b(servers["B"].port, tokens.at("viewer")), on_p(servers["P"].port, tokens.at("viewer"));
  ASSERT_TRUE(on_b.wait_connected() && on_p.wait_connected()) << logs();

  // Models PUT on A: each commits a model.new event with its version.
  constexpr int kModels = 5;
  const auto plant = read_file_bytes(data_file("reference_pump/plant.json").string());
  for (int i = 0; i < kModels; ++i) {
    const auto r = client_on("A").Put("/api/v1/pumps/P-101/model", auth("engineer"), plant, "application/json");
    ASSERT_TRUE(r && r->status == 200) << (r ? r->body : "") << logs();
  }
  // Events a writer of its own commits, at random moments (a poll's phase
  // is then uniform): the time from the commit's return to each stream.
  constexpr int kEvents = 40;
  auto writer = storage::Historian::open(db.string());
  std::vector<std::chrono::steady_clock::time_point> committed;
  std::mt19937 rng(22);
  for (int i = 0; i < kEvents; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20 + rng() % 80));
    writer.append_event("test.tick", "P-101", "{\"n\":\"" + std::to_string(i) + "\"}");
    committed.push_back(std::chrono::steady_clock::now());
  }
  for (auto* s : {&on_b, &on_p}) ASSERT_TRUE(s->wait_for("test.tick", "n", std::to_string(kEvents - 1), 60s)) << s->seen();

  for (auto* s : {&on_b, &on_p}) {
    const auto models = of_type(*s, "model.new");
    ASSERT_EQ(models.size(), static_cast<std::size_t>(kModels)) << s->seen();
    for (int i = 0; i < kModels; ++i) EXPECT_EQ(models[i].data.value("model_version", 0), i + 1) << s->seen();
    const auto ticks = of_type(*s, "test.tick");
    ASSERT_EQ(ticks.size(), static_cast<std::size_t>(kEvents)) << s->seen();
    for (int i = 0; i < kEvents; ++i) EXPECT_EQ(ticks[i].data["n"], std::to_string(i));
    // Ids grow: every event once, in seq order.
    const auto all = s->events();
    for (std::size_t i = 1; i < all.size(); ++i) EXPECT_LT(std::stoll(all[i - 1].id), std::stoll(all[i].id)) << s->seen();
  }
  EXPECT_EQ(on_b.events().size(), on_p.events().size());
  EXPECT_GT(metric_on("B", "ambdiag_event_notifications_total"), 0) << "B's events did not come by notification";
  EXPECT_EQ(metric_on("P", "ambdiag_event_notifications_total"), 0);

  for (auto [s, what] : {std::pair{&on_b, "LISTEN/NOTIFY"}, std::pair{&on_p, "poll every 250 ms"}}) {
    const auto ticks = of_type(*s, "test.tick");
    std::vector<double> ms;
    for (int i = 0; i < kEvents; ++i)
      ms.push_back(std::chrono::duration<double, std::milli>(ticks[i].at - committed[i]).count());
    print_latencies(what, ms);
  }
}

}  // namespace
}  // namespace ambdiag::testing
