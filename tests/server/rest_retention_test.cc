// The retention routes on a real server and file: GET (viewer) shows the
// effective policy and where it comes from, PUT (engineer) makes a version
// with who made it, a bad policy is 400 naming the key with nothing stored,
// an unknown pump 404; after a sweep the run says its samples were dropped
// and samples.f32 is 410 naming the run and the date; /metrics counts it.
#include <gtest/gtest.h>
#include <httplib.h>

#include "ambdiag/server/metrics.h"
#include "ambdiag/server/rest_server.h"
#include "ambdiag/server/retention_service.h"
#include "ambdiag/storage/historian.h"
#include "ambdiag/storage/recording_io.h"
#include "rest_request.h"
#include "test_support.h"

namespace ambdiag::server {
namespace {

using nlohmann::json;
using storage::Historian;
using storage::Role;

constexpr const char* kRun = "/api/v1/runs/P-101%2F2026-11-21T10%3A00%3A00Z";
constexpr const char* kPolicy = "/api/v1/pumps/P-101/retention";

class RestRetention : public ::testing::Test {
 protected:
  void SetUp() override {
    db_ = (ambdiag::testing::scratch_dir() / "h.db").string();
    {
      auto h = Historian::open(db_);
      storage::import_recording(h, ambdiag::testing::data_file("reference_pump/run_ref_1").string());
      viewer_ = h.add_token("vera", Role::viewer);
      operator_ = h.add_token("otto", Role::operator_);
      engineer_ = h.add_token("erin", Role::engineer);
    }
    RetentionOptions o;
    o.db_path = db_;
    o.defaults.samples_days = 30;
    o.interval = std::chrono::milliseconds(0);  // swept by the test
    o.metrics = &metrics_;
    o.verbose = false;
    retention_ = std::make_unique<RetentionService>(o);
  }

  // The REST server, with the retention service or without (once per test).
  void start_server(RetentionService* retention) {
    RestOptions r;
    r.db_path = db_;
    r.host = "127.0.0.1";
    r.retention = retention;
    r.metrics = &metrics_;
    server_ = std::make_unique<RestServer>(r);
    port_ = server_->start();
  }

  httplib::Result request(const std::string& method, const std::string& path, const std::string& token,
                          const std::string& body = "") {
    return rest_request(port_, method, path, token, body);
  }
  static json body(const httplib::Result& r) { return json::parse(r->body); }

  std::string db_, viewer_, operator_, engineer_;
  MetricsRegistry metrics_;
  std::unique_ptr<RetentionService> retention_;
  std::unique_ptr<RestServer> server_;
  int port_ = 0;
};

TEST_F(RestRetention, AViewerSeesTheEffectivePolicyAndAnEngineerSetsTheKeysItChanges) {
  start_server(retention_.get());
  auto r = request("GET", kPolicy, viewer_);
  ASSERT_EQ(r->status, 200) << r->body;
  auto j = body(r);
  EXPECT_EQ(j["source"], "defaults");
  EXPECT_EQ(j["policy"], j["defaults"]);
  EXPECT_EQ(j["policy"]["samples_days"], 30);
  EXPECT_EQ(j["policy"]["frf_days"], 730);
  EXPECT_TRUE(j["policy"]["monitoring_days"].is_null());
  EXPECT_EQ(j["override"], json::object());
  EXPECT_FALSE(j.contains("version"));
  EXPECT_EQ(j["usage"]["runs_with_samples"], 1);
  EXPECT_EQ(j["usage"]["samples_bytes_held"], 6553600);

  EXPECT_EQ(request("PUT", kPolicy, viewer_, R"({"samples_days": 7})")->status, 403);
  EXPECT_EQ(request("PUT", kPolicy, operator_, R"({"samples_days": 7})")->status, 403);
  EXPECT_EQ(request("PUT", kPolicy, "", R"({"samples_days": 7})")->status, 401);
  r = request("PUT", kPolicy, engineer_, R"({"samples_days": 7, "monitoring_days": 14})");
  ASSERT_EQ(r->status, 200) << r->body;
  j = body(r);
  EXPECT_EQ(j["source"], "pump");
  EXPECT_EQ(j["version"], 1);
  EXPECT_EQ(j["created_by"], "erin");
  EXPECT_EQ(j["policy"]["samples_days"], 7);
  EXPECT_EQ(j["policy"]["monitoring_days"], 14);
  EXPECT_EQ(j["policy"]["frf_days"], 730) << "not given: the server's default";
  EXPECT_EQ(j["override"], json::parse(R"({"samples_days": 7, "monitoring_days": 14})"));
  EXPECT_EQ(body(request("GET", kPolicy, viewer_)), j);

  // null keeps for ever; {} goes back to the defaults. Each PUT is a version.
  ASSERT_EQ(request("PUT", kPolicy, engineer_, R"({"samples_days": null})")->status, 200);
  EXPECT_TRUE(body(request("GET", kPolicy, viewer_))["policy"]["samples_days"].is_null());
  r = request("PUT", kPolicy, engineer_, "{}");
  ASSERT_EQ(r->status, 200);
  EXPECT_EQ(body(r)["policy"], body(r)["defaults"]);
  r = request("GET", std::string(kPolicy) + "/history", viewer_);
  ASSERT_EQ(r->status, 200) << r->body;
  const auto versions = body(r)["versions"];
  ASSERT_EQ(versions.size(), 3u);
  EXPECT_EQ(versions[0]["version"], 1);
  EXPECT_EQ(versions[0]["created_by"], "erin");
  EXPECT_EQ(versions[1]["override"], json::parse(R"({"samples_days": null})"));
  EXPECT_FALSE(versions[2]["created_at"].get<std::string>().empty());
}

TEST_F(RestRetention, ABadPolicyIs400NamingTheKeyAndAnUnknownPump404) {
  start_server(retention_.get());
  const auto error = [&](const std::string& policy) {
    const auto r = request("PUT", kPolicy, engineer_, policy);
    EXPECT_EQ(r->status, 400) << policy;
    return body(r)["error"].get<std::string>();
  };
  EXPECT_EQ(error(R"({"samples_days": "7"})").rfind("retention: samples_days: must be a number of days", 0), 0u);
  EXPECT_EQ(error(R"({"samples_bytes": -1})").rfind("retention: samples_bytes:", 0), 0u);
  EXPECT_EQ(error(R"({"frf_days": 1e9})").rfind("retention: frf_days:", 0), 0u);
  EXPECT_EQ(error(R"({"samples_dayz": 7})").rfind("retention: samples_dayz: unknown key", 0), 0u);
  EXPECT_NE(error("[7]").find("must be a JSON object"), std::string::npos);
  EXPECT_NE(error("{nope").find("retention"), std::string::npos);
  EXPECT_EQ(body(request("GET", kPolicy, viewer_))["source"], "defaults") << "nothing stored";
  EXPECT_EQ(request("GET", "/api/v1/pumps/P-404/retention", viewer_)->status, 404);
  EXPECT_EQ(request("PUT", "/api/v1/pumps/P-404/retention", engineer_, "{}")->status, 404);
  EXPECT_EQ(request("GET", "/api/v1/pumps/P-404/retention/history", viewer_)->status, 404);
}

TEST_F(RestRetention, AfterASweepTheRunSaysItsSamplesWereDroppedAndTheirDownloadIsGone) {
  start_server(retention_.get());
  auto r = request("GET", kRun, viewer_);
  ASSERT_EQ(r->status, 200);
  EXPECT_EQ(body(r)["samples"], "held");
  EXPECT_EQ(request("GET", std::string(kRun) + "/samples.f32", viewer_)->body.size(), 6553600u);
  ASSERT_EQ(request("PUT", kPolicy, engineer_, R"({"samples_days": 0})")->status, 200);
  const auto report = retention_->sweep_now();
  EXPECT_EQ(report.samples_runs, 1);

  r = request("GET", kRun, viewer_);
  ASSERT_EQ(r->status, 200);
  const auto run = body(r);
  EXPECT_EQ(run["status"], "complete");
  EXPECT_EQ(run["samples"], "dropped");
  EXPECT_EQ(run["samples_dropped_bytes"], 6553600);
  EXPECT_EQ(run["samples_bytes"], 6553600) << "what the run received";
  const std::string at = run["samples_dropped_at"];
  r = request("GET", std::string(kRun) + "/samples.f32", viewer_);
  EXPECT_EQ(r->status, 410);
  const std::string e = body(r)["error"];
  EXPECT_NE(e.find("run 'P-101/2026-11-21T10:00:00Z': its samples were dropped by retention at " + at), std::string::npos) << e;
  EXPECT_EQ(body(request("GET", "/api/v1/pumps/P-101/runs", viewer_))["runs"][0]["samples"], "dropped");
  EXPECT_EQ(body(request("GET", kPolicy, viewer_))["usage"]["runs_samples_dropped"], 1);

  const std::string m = request("GET", "/metrics", "")->body;
  EXPECT_NE(m.find("ambdiag_retention_dropped_bytes_total{what=\"samples\"} 6553600"), std::string::npos) << m;
  EXPECT_NE(m.find("ambdiag_retention_dropped_runs_total{what=\"samples\"} 1"), std::string::npos);
  EXPECT_NE(m.find("ambdiag_retention_sweeps_total{outcome=\"done\"} 1"), std::string::npos);
  EXPECT_EQ(m.find("ambdiag_retention_last_sweep_timestamp_seconds 0\n"), std::string::npos) << "set by the sweep";
  EXPECT_EQ(retention_->last_sweep()["samples"]["bytes"], 6553600);
}

TEST_F(RestRetention, WithoutTheRetentionServiceTheBuiltInDefaultsShowAndAPutIs503) {
  start_server(nullptr);
  auto r = request("GET", kPolicy, viewer_);
  ASSERT_EQ(r->status, 200);
  EXPECT_EQ(body(r)["policy"], storage::to_json(storage::RetentionPolicy{}));
  r = request("PUT", kPolicy, engineer_, "{}");
  EXPECT_EQ(r->status, 503);
  EXPECT_NE(body(r)["error"].get<std::string>().find("retention service"), std::string::npos);
}

}  // namespace
}  // namespace ambdiag::server
