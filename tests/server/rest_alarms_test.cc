// The alarm routes on a real server and file: roles (a viewer cannot
// acknowledge, an operator can), 409 for an ack the state does not allow,
// 404 for an unknown alarm, bad rules 400 naming the field, the journal by
// cursor with who did what, the KPIs.
#include <gtest/gtest.h>
#include <httplib.h>

#include "ambdiag/server/analysis_service.h"
#include "ambdiag/server/rest_server.h"
#include "ambdiag/storage/historian.h"
#include "ambdiag/storage/recording_io.h"
#include "alarm_seed.h"
#include "rest_request.h"
#include "test_support.h"

namespace ambdiag::server {
namespace {

using nlohmann::json;
using storage::Historian;
using storage::Role;

class RestAlarms : public ::testing::Test {
 protected:
  void SetUp() override {
    db_ = (ambdiag::testing::scratch_dir() / "h.db").string();
    writer_.emplace(Historian::open(db_));
    storage::import_recording(*writer_, ambdiag::testing::data_file("reference_pump/run_ref_1").string());
    viewer_ = writer_->add_token("vera", Role::viewer);
    operator_ = writer_->add_token("otto", Role::operator_);
    engineer_ = writer_->add_token("erin", Role::engineer);
    AnalysisOptions a;
    a.db_path = db_;
    a.verbose = false;
    a.on_alarm_event = [this](const json& e) {
      std::lock_guard l(mu_);
      heard_.push_back(e);
    };
    analysis_ = std::make_unique<AnalysisService>(a);
    RestOptions r;
    r.db_path = db_;
    r.host = "127.0.0.1";
    r.analysis = analysis_.get();
    server_ = std::make_unique<RestServer>(r);
    port_ = server_->start();
  }

  // An active alarm of the pump, raised by the server.
  std::int64_t seed_alarm(const std::string& rule) {
    return server::seed_alarm(*writer_, "P-101", rule, "P-101/2026-11-21T10:00:00Z");
  }

  httplib::Result request(const std::string& method, const std::string& path, const std::string& token,
                          const std::string& body = "") {
    return rest_request(port_, method, path, token, body);
  }
  static json body(const httplib::Result& r) { return json::parse(r->body); }

  std::string db_, viewer_, operator_, engineer_;
  std::optional<Historian> writer_;
  std::unique_ptr<AnalysisService> analysis_;
  std::unique_ptr<RestServer> server_;
  int port_ = 0;
  std::mutex mu_;
  std::vector<json> heard_;
};

TEST_F(RestAlarms, AnOperatorAcknowledgesAViewerCannotAndTheHistoryShowsWho) {
  const auto id = seed_alarm("fault.balance_piston_wear");
  const std::string url = "/api/v1/alarms/" + std::to_string(id);
  auto r = request("POST", url + "/ack", viewer_, R"({"comment": "mine"})");
  ASSERT_EQ(r->status, 403) << r->body;
  EXPECT_EQ(request("POST", url + "/ack", "", "{}")->status, 401);
  r = request("POST", url + "/ack", operator_, R"({"comment": "piston wear known, planned for the outage"})");
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(body(r)["state"], "ack_active");
  EXPECT_EQ(body(r)["acknowledged"], true);
  // A second ack: the state allows none.
  r = request("POST", url + "/ack", operator_, "");
  EXPECT_EQ(r->status, 409) << r->body;
  EXPECT_NE(body(r)["error"].get<std::string>().find("ack_active"), std::string::npos);
  // The history, oldest first, with who.
  r = request("GET", url + "/history", viewer_);
  ASSERT_EQ(r->status, 200);
  const json events = body(r)["events"];
  ASSERT_EQ(events.size(), 2u) << events.dump();
  EXPECT_EQ(events[0]["by"], "server");
  EXPECT_EQ(events[0]["from"], "normal");
  EXPECT_EQ(events[1]["by"], "otto");
  EXPECT_EQ(events[1]["from"], "unack_active");
  EXPECT_EQ(events[1]["to"], "ack_active");
  EXPECT_EQ(events[1]["comment"], "piston wear known, planned for the outage");
  EXPECT_LT(events[0]["seq"].get<int>(), events[1]["seq"].get<int>());
  std::lock_guard l(mu_);
  ASSERT_EQ(heard_.size(), 1u) << "the hook heard the ack";
  EXPECT_EQ(heard_[0]["alarm_id"], id);
}

TEST_F(RestAlarms, UnknownAlarmsAre404AndBadRequests400) {
  EXPECT_EQ(request("POST", "/api/v1/alarms/999/ack", operator_, "{}")->status, 404);
  EXPECT_EQ(request("GET", "/api/v1/alarms/999/history", viewer_)->status, 404);
  EXPECT_EQ(request("GET", "/api/v1/alarms/abc", viewer_)->status, 400);
  EXPECT_EQ(request("GET", "/api/v1/alarms?state=bogus", viewer_)->status, 400);
  EXPECT_EQ(request("GET", "/api/v1/alarms?active=maybe", viewer_)->status, 400);
  EXPECT_EQ(request("GET", "/api/v1/alarm-events?after_seq=-1", viewer_)->status, 400);
  EXPECT_EQ(request("GET", "/api/v1/alarm-kpis?from=yesterday", viewer_)->status, 400);
  const auto id = seed_alarm("detection");
  const std::string url = "/api/v1/alarms/" + std::to_string(id);
  EXPECT_EQ(request("POST", url + "/ack", operator_, "[1]")->status, 400);
  EXPECT_EQ(request("POST", url + "/shelve", operator_, R"({"minutes": 30})")->status, 400) << "a comment is required";
  EXPECT_EQ(request("POST", url + "/shelve", operator_, R"({"minutes": "30", "comment": "x"})")->status, 400);
  EXPECT_EQ(request("POST", url + "/unshelve", operator_, "{}")->status, 409);
  EXPECT_EQ(request("POST", url + "/reset", operator_, R"({"comment": "x"})")->status, 403) << "engineers reset";
  EXPECT_EQ(request("POST", url + "/reset", engineer_, R"({"comment": "x"})")->status, 409) << "not latched";
  // Nothing changed by the refused requests.
  EXPECT_EQ(body(request("GET", url, viewer_))["state"], "unack_active");
  EXPECT_EQ(body(request("GET", url + "/history", viewer_))["events"].size(), 1u);
}

TEST_F(RestAlarms, ShelveAndUnshelveAndTheListFilters) {
  const auto id = seed_alarm("detection");
  seed_alarm("poor_data");
  const std::string url = "/api/v1/alarms/" + std::to_string(id);
  auto r = request("POST", url + "/shelve", operator_, R"({"minutes": 60, "comment": "sensor work"})");
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(body(r)["state"], "shelved");
  EXPECT_TRUE(body(r).contains("shelved_until"));
  auto list = body(request("GET", "/api/v1/alarms?state=shelved", viewer_))["alarms"];
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0]["alarm_id"], id);
  list = body(request("GET", "/api/v1/alarms?pump_id=P-101&active=true", viewer_))["alarms"];
  ASSERT_EQ(list.size(), 2u);
  EXPECT_GT(list[0]["alarm_id"].get<int>(), list[1]["alarm_id"].get<int>()) << "newest first";
  for (const char* key : {"alarm_id", "pump_id", "rule", "severity", "state", "active", "acknowledged", "raised_at", "run_id", "message"})
    EXPECT_TRUE(list[0].contains(key)) << key;
  r = request("POST", url + "/unshelve", operator_, "");
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(body(r)["state"], "unack_active");
  // The pump view counts the active alarms; a high one makes its health an alarm.
  const auto pump = body(request("GET", "/api/v1/pumps/P-101", viewer_));
  EXPECT_EQ(pump["active_alarms"], 2);
  EXPECT_EQ(pump["health"], "alarm");
}

TEST_F(RestAlarms, TheJournalIsPolledByCursor) {
  seed_alarm("detection");
  seed_alarm("poor_data");
  seed_alarm("stale_data");
  auto r = body(request("GET", "/api/v1/alarm-events?after_seq=0&limit=2", viewer_));
  ASSERT_EQ(r["events"].size(), 2u);
  const auto next = r["next_seq"].get<int>();
  EXPECT_EQ(next, r["events"][1]["seq"].get<int>());
  for (const char* key : {"seq", "alarm_id", "pump_id", "time", "from", "to", "by"}) EXPECT_TRUE(r["events"][0].contains(key)) << key;
  r = body(request("GET", "/api/v1/alarm-events?after_seq=" + std::to_string(next), viewer_));
  ASSERT_EQ(r["events"].size(), 1u);
  EXPECT_EQ(r["events"][0]["rule"], "stale_data");
  const auto last = r["next_seq"].get<int>();
  r = body(request("GET", "/api/v1/alarm-events?after_seq=" + std::to_string(last), viewer_));
  EXPECT_TRUE(r["events"].empty());
  EXPECT_EQ(r["next_seq"], last) << "nothing new: the same cursor";
}

TEST_F(RestAlarms, RulesArePutByEngineersValidatedAndVersioned) {
  auto r = request("GET", "/api/v1/pumps/P-101/alarm-rules", viewer_);
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(body(r)["source"], "defaults");
  EXPECT_EQ(body(r)["version"], 0);
  const std::string rules = R"({"rules": [{"id": "detection", "on_delay": {"k": 3, "n": 5}}]})";
  EXPECT_EQ(request("PUT", "/api/v1/pumps/P-101/alarm-rules", operator_, rules)->status, 403);
  r = request("PUT", "/api/v1/pumps/P-101/alarm-rules", engineer_,
              R"({"rules": [{"id": "detection"}, {"id": "poor_data"}, {"id": "stale_data", "on_delay": {"k": 4, "n": 2}}]})");
  ASSERT_EQ(r->status, 400);
  EXPECT_EQ(body(r)["error"], "rules[2].on_delay.k: must be <= n (2)");
  EXPECT_EQ(request("PUT", "/api/v1/pumps/P-101/alarm-rules", engineer_, "{not json")->status, 400);
  EXPECT_EQ(request("PUT", "/api/v1/pumps/P-404/alarm-rules", engineer_, rules)->status, 404);
  EXPECT_EQ(body(request("GET", "/api/v1/pumps/P-101/alarm-rules", viewer_))["version"], 0) << "nothing stored";
  r = request("PUT", "/api/v1/pumps/P-101/alarm-rules", engineer_, rules);
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(body(r)["version"], 1);
  EXPECT_EQ(body(r)["created_by"], "erin");
  r = request("PUT", "/api/v1/pumps/P-101/alarm-rules", engineer_, rules);
  EXPECT_EQ(body(r)["version"], 2) << "every PUT a new version";
  const auto got = body(request("GET", "/api/v1/pumps/P-101/alarm-rules", viewer_));
  EXPECT_EQ(got["source"], "pump");
  bool found = false;
  for (const auto& rule : got["rules"])
    if (rule["id"] == "detection") {
      found = true;
      EXPECT_EQ(rule["on_delay"]["k"], 3);
      EXPECT_EQ(rule["clear"], 0.8);
    }
  EXPECT_TRUE(found);
  // What GET gives can be PUT back as it is.
  EXPECT_EQ(request("PUT", "/api/v1/pumps/P-101/alarm-rules", engineer_, got.dump())->status, 200);
}

TEST_F(RestAlarms, KpisCountRaisesPerTenMinutesFloodsAndTheTop) {
  for (const char* rule : {"detection", "poor_data", "stale_data"}) seed_alarm(rule);
  auto r = request("GET", "/api/v1/alarm-kpis?from=2026-11-26T09:00:00Z&to=2026-11-26T11:00:00Z", viewer_);
  ASSERT_EQ(r->status, 200) << r->body;
  const json k = body(r);
  EXPECT_EQ(k["raises"], 3);
  EXPECT_EQ(k["intervals_10min"], 12);
  EXPECT_DOUBLE_EQ(k["alarms_per_10min"]["average"].get<double>(), 3.0 / 12.0);
  EXPECT_EQ(k["alarms_per_10min"]["peak"], 3);
  EXPECT_EQ(k["flood"]["intervals"], 0);
  EXPECT_EQ(k["chattering"]["alarms"].size(), 0u) << "three rules, one raise each";
  EXPECT_EQ(k["top"].size(), 3u);
  EXPECT_EQ(request("GET", "/api/v1/alarm-kpis?from=2026-11-26T11:00:00Z&to=2026-11-26T10:00:00Z", viewer_)->status, 400);
}

}  // namespace
}  // namespace ambdiag::server
