// Trends over real HTTP on an ephemeral port against a real historian file:
// series, points, buckets and pages with the reference band, the prognosis
// of a wearing seal, the Grafana data source, and bad requests refused with
// the parameter named. The points are put as the job runner puts them: with
// an analysis job's result (finish_job).
#include <gtest/gtest.h>
#include <httplib.h>

#include <cmath>
#include <tuple>

#include "../storage/historian_fixture.h"
#include "ambdiag/server/rest_server.h"
#include "ambdiag/storage/historian.h"
#include "alarms/alarm_state.h"
#include "test_support.h"

namespace ambdiag::server {
namespace {

using nlohmann::json;
using storage::Historian;
using storage::SeriesValue;

constexpr std::int64_t kDayNs = 86'400'000'000'000;
const std::int64_t kT0 = storage::ns_from_utc("2026-01-01T00:00:00Z", "t0");
const std::string kMode = "mode.radial bending 1 (forward).f_hz";
const std::string kWear = "fault.impeller_seal_wear.clearance_factor";

class TrendRest : public ::testing::Test {
 protected:
  void SetUp() override {
    db_path_ = (ambdiag::testing::scratch_dir() / "h.db").string();
    h_.emplace(Historian::open(db_path_));
  }

  // A complete identification run of P-1, day `day`, analysed with these values.
  std::string analysed_run(int day, const std::vector<SeriesValue>& values, const std::string& pump_id = "P-1") {
    const std::string run_id = pump_id + "/d" + std::to_string(day);
    auto j = json::parse(ambdiag::testing::identification_json_text(run_id, pump_id, 1));
    j["started_at"] = storage::utc_from_ns(kT0 + day * kDayNs);
    h_->begin_run(storage::run_header_from_json(j.dump()));
    const auto bytes = ambdiag::testing::samples_bytes(300, 1, static_cast<unsigned>(day));
    h_->put_chunks(run_id, ambdiag::testing::cut_chunks(bytes, 1, 100));
    h_->end_run(run_id, 300, ambdiag::testing::checksum_of(bytes));
    const auto [id, created] = h_->enqueue_job({"analysis", pump_id, run_id, 1, 0});
    const auto job = h_->claim_job("test");
    EXPECT_TRUE(job && job->job_id == id);
    EXPECT_TRUE(h_->finish_job(id, job->attempts, "{}", {}, values));
    return run_id;
  }

  // 30 daily runs: the mode steady near 50 Hz, the seal's clearance factor
  // growing 0.02 a day from 1 (2 at day 50), detection firing from day 25.
  void wearing_pump() {
    for (int d = 0; d < 30; ++d) {
      const double wobble = (d % 3 - 1) * 0.01;
      runs_.push_back(analysed_run(d, {{kMode, "Hz", 50.0 + wobble, 0.05},
                                       {kWear, "1", 1.0 + 0.02 * d + wobble, 0.01},
                                       {"detection.ratio", "1", d >= 25 ? 1.5 : 0.4, std::nullopt}}));
    }
  }

  void start(bool anonymous = true) {
    RestOptions opt;
    opt.anonymous_read = anonymous;
    opt.db_path = db_path_;
    opt.host = "127.0.0.1";
    server_ = std::make_unique<RestServer>(std::move(opt));
    port_ = server_->start();
  }

  httplib::Result get(const std::string& path) {
    httplib::Client c("127.0.0.1", port_);
    c.set_read_timeout(10, 0);
    return c.Get(path);
  }
  httplib::Result post(const std::string& path, const json& body, const std::string& token = "") {
    httplib::Client c("127.0.0.1", port_);
    c.set_read_timeout(10, 0);
    httplib::Headers headers;
    if (!token.empty()) headers.emplace("Authorization", "Bearer " + token);
    return c.Post(path, headers, body.dump(), "application/json");
  }
  static json body(const httplib::Result& r) { return json::parse(r->body); }

  // The status, and the error naming `what` for a refusal.
  void expect_error(const std::string& path, int status, const std::string& what) {
    const auto r = get(path);
    ASSERT_TRUE(r) << path;
    EXPECT_EQ(r->status, status) << path << ": " << r->body;
    EXPECT_NE(body(r).value("error", "").find(what), std::string::npos) << path << ": " << r->body;
  }

  std::string db_path_;
  std::optional<Historian> h_;
  std::vector<std::string> runs_;
  std::unique_ptr<RestServer> server_;
  int port_ = 0;
};

std::string enc(const std::string& s) { return url_encode_segment(s); }

TEST_F(TrendRest, ListsThePumpsSeriesWithUnits) {
  wearing_pump();
  storage::MonitoringSnapshot m;
  m.pump_id = "P-1";
  m.time_ns = kT0;
  m.speed_rpm = 3000;
  h_->put_monitoring(std::vector<storage::MonitoringSnapshot>{m});
  start();
  const auto r = get("/api/v1/pumps/P-1/series");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);
  const auto j = body(r);
  std::map<std::string, std::string> units;
  for (const auto& s : j["series"]) units[s["name"]] = s["unit"];
  EXPECT_EQ(units.at(kMode), "Hz");
  EXPECT_EQ(units.at(kWear), "1");
  EXPECT_EQ(units.at("detection.ratio"), "1");
  EXPECT_EQ(units.at("monitoring.speed_rpm"), "rpm");
  EXPECT_EQ(units.at("monitoring.orbit_major_m.b"), "m");
  expect_error("/api/v1/pumps/P-9/series", 404, "P-9");
}

TEST_F(TrendRest, PointsOldestFirstWithRunAndReferenceBand) {
  wearing_pump();
  h_->put_reference("P-1", {runs_[0], runs_[1], runs_[2], runs_[3]}, "test");
  start();
  const auto r = get("/api/v1/pumps/P-1/trends?series=" + enc(kMode) + "&series=detection.ratio&from=" +
                     enc(storage::utc_from_ns(kT0 + 10 * kDayNs)) + "&to=" + std::to_string(kT0 + 19 * kDayNs));
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  const auto j = body(r);
  ASSERT_EQ(j["series"].size(), 2u);
  const auto& mode = j["series"][0];
  EXPECT_EQ(mode["name"], kMode);
  EXPECT_EQ(mode["unit"], "Hz");
  EXPECT_FALSE(mode["truncated"]);
  ASSERT_EQ(mode["points"].size(), 10u);  // days 10..19, both edges in
  const auto& first = mode["points"][0];
  EXPECT_EQ(first["time"], "2026-01-11T00:00:00Z");
  EXPECT_EQ(first["run_id"], "P-1/d10");
  EXPECT_NEAR(first["value"].get<double>(), 50.0 + (10 % 3 - 1) * 0.01, 1e-12);
  EXPECT_DOUBLE_EQ(first["sd"].get<double>(), 0.05);
  EXPECT_EQ(mode["points"][9]["run_id"], "P-1/d19");
  // The band of days 0..3: 49.99, 50, 50.01, 49.99.
  const auto& band = mode["reference"];
  EXPECT_EQ(band["runs"], 4);
  EXPECT_NEAR(band["mean"].get<double>(), 49.9975, 1e-9);
  // Deviations -0.0075, 0.0025, 0.0125, -0.0075; sd with n - 1.
  EXPECT_NEAR(band["sd"].get<double>(), std::sqrt((2 * 0.0075 * 0.0075 + 0.0025 * 0.0025 + 0.0125 * 0.0125) / 3.0), 1e-9);
  // The alarm limits drawn on each series (the built-in rules: the mode's
  // relative to this band, detection at its ratio levels; alarm_limits_test
  // checks the numbers against the rules).
  ASSERT_TRUE(mode.contains("limits")) << mode.dump();
  EXPECT_EQ(mode["limits"]["rule"], "mode.*.f_hz");
  for (const auto& line : mode["limits"]["lines"])  // every line at least the minimum shift away from the mean
    EXPECT_GE(std::abs(line["value"].get<double>() - band["mean"].get<double>()), 0.01 * band["mean"].get<double>()) << line;
  ASSERT_TRUE(j["series"][1].contains("limits"));
  EXPECT_EQ(j["series"][1]["limits"]["rule"], "detection");
  EXPECT_FALSE(j["series"][1]["points"][0].contains("sd"));
}

TEST_F(TrendRest, PastMaxPointsBucketsKeepThePeaksAndRawPagesSayHowToGoOn) {
  wearing_pump();
  start();
  auto r = get("/api/v1/pumps/P-1/trends?series=" + enc(kWear) + "&max_points=7");
  ASSERT_EQ(r->status, 200) << r->body;
  auto s = body(r)["series"][0];
  EXPECT_EQ(s["count"], 30);
  ASSERT_LE(s["points"].size(), 7u);
  double hi = 0;
  std::int64_t n = 0;
  for (const auto& b : s["points"]) {
    hi = std::max(hi, b["max"].get<double>());
    n += b["count"].get<std::int64_t>();
    EXPECT_LE(b["min"].get<double>(), b["first"].get<double>());
  }
  EXPECT_EQ(n, 30);
  EXPECT_NEAR(hi, 1.0 + 0.02 * 29 + 0.01, 1e-12);  // day 29's value, the largest
  EXPECT_GT(s["bucket_s"].get<double>(), 4 * 86400.0);

  r = get("/api/v1/pumps/P-1/trends?series=" + enc(kWear) + "&max_points=12&raw=true");
  ASSERT_EQ(r->status, 200);
  auto j = body(r);
  EXPECT_TRUE(j["truncated"]);
  s = j["series"][0];
  EXPECT_TRUE(s["truncated"]);
  ASSERT_EQ(s["points"].size(), 12u);
  EXPECT_EQ(s["next_from"], "2026-01-13T00:00:00Z");
  r = get("/api/v1/pumps/P-1/trends?series=" + enc(kWear) + "&max_points=100&raw=true&from=" + enc(s["next_from"]));
  s = body(r)["series"][0];
  EXPECT_FALSE(s["truncated"]);
  ASSERT_EQ(s["points"].size(), 18u);
  EXPECT_EQ(s["points"][0]["run_id"], "P-1/d12");
}

TEST_F(TrendRest, BadTrendRequestsNameWhatIsWrong) {
  wearing_pump();
  start();
  const std::string base = "/api/v1/pumps/P-1/trends?series=detection.ratio";
  expect_error("/api/v1/pumps/P-1/trends?series=no.such", 404, "no.such");
  expect_error("/api/v1/pumps/P-9/trends?series=detection.ratio", 404, "P-9");
  expect_error("/api/v1/pumps/P-1/trends", 400, "series");
  expect_error(base + "&max_points=0", 400, "max_points");
  expect_error(base + "&max_points=ten", 400, "max_points");
  expect_error(base + "&max_points=100001", 400, "max_points");
  expect_error(base + "&from=yesterday", 400, "from");
  expect_error(base + "&to=2026-13-01T00:00:00Z", 400, "to");
  expect_error(base + "&from=2026-02-01T00:00:00Z&to=2026-01-01T00:00:00Z", 400, "from");
  expect_error(base + "&raw=yes", 400, "raw");
  expect_error(base + "&max_point=5", 400, "max_point");
  std::string many = "/api/v1/pumps/P-1/trends?";
  for (int i = 0; i < 21; ++i) many += "series=s" + std::to_string(i) + "&";
  expect_error(many, 400, "series");
}

TEST_F(TrendRest, PrognosisOfTheWearingSealReachesTheDefaultLimitAroundDay50) {
  wearing_pump();
  start();
  auto r = get("/api/v1/pumps/P-1/prognosis?series=" + enc(kWear));
  ASSERT_EQ(r->status, 200) << r->body;
  auto j = body(r);
  EXPECT_EQ(j["status"], "ok") << j.dump();
  EXPECT_EQ(j["limit"], 2.0);
  EXPECT_EQ(j["limit_source"], "default");
  EXPECT_EQ(j["points"], 30);
  EXPECT_TRUE(j["weighted"]);
  const auto at = storage::ns_from_utc(j["estimated_at"], "estimated_at");
  EXPECT_NEAR(static_cast<double>(at - kT0) / kDayNs, 50.0, 1.0);
  EXPECT_LT(storage::ns_from_utc(j["interval"]["from"], "from"), at);
  EXPECT_GT(storage::ns_from_utc(j["interval"]["to"], "to"), at);
  EXPECT_NEAR(j["slope_per_day"].get<double>(), 0.02, 1e-3);

  // Four runs only: no guess.
  r = get("/api/v1/pumps/P-1/prognosis?series=" + enc(kWear) + "&to=" + enc(storage::utc_from_ns(kT0 + 3 * kDayNs)));
  EXPECT_EQ(body(r)["status"], "not enough points");
  EXPECT_FALSE(body(r).contains("estimated_at"));
  // The steady mode does not trend towards 60 Hz.
  r = get("/api/v1/pumps/P-1/prognosis?series=" + enc(kMode) + "&limit=60");
  EXPECT_EQ(body(r)["status"], "not trending towards the limit") << r->body;
  expect_error("/api/v1/pumps/P-1/prognosis?series=" + enc(kMode), 400, "limit");
  expect_error("/api/v1/pumps/P-1/prognosis?series=" + enc(kMode) + "&limit=abc", 400, "limit");
  expect_error("/api/v1/pumps/P-1/prognosis?series=fault.x.y&limit=2", 404, "fault.x.y");
  expect_error("/api/v1/pumps/P-1/prognosis?series=a&series=b&limit=2", 400, "series");
}

TEST_F(TrendRest, GrafanaDataSourceAnswersTheJsonApi) {
  wearing_pump();
  start();
  auto r = get("/api/v1/grafana/");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  // Metrics: every PUMP:SERIES (a server without the analysis service serves these POSTs).
  r = post("/api/v1/grafana/metrics", json::object());
  ASSERT_EQ(r->status, 200) << r->body;
  bool listed = false;
  for (const auto& m : body(r)) listed = listed || m["value"] == "P-1:" + kWear;
  EXPECT_TRUE(listed) << r->body;
  EXPECT_TRUE(body(post("/api/v1/grafana/search", {{"target", ""}})).is_array());
  auto vars = body(post("/api/v1/grafana/variable", {{"payload", {{"target", "pumps"}}}}));
  ASSERT_EQ(vars.size(), 1u);
  EXPECT_EQ(vars[0]["__value"], "P-1");
  vars = body(post("/api/v1/grafana/variable", {{"payload", {{"target", "series:P-1"}}}}));
  EXPECT_EQ(vars.size(), 3u);
  EXPECT_EQ(post("/api/v1/grafana/variable", {{"payload", {{"target", "tags"}}}})->status, 400);

  const json q = {{"range", {{"from", "2026-01-01T00:00:00.000Z"}, {"to", "2026-01-30T12:00:00.000Z"}}},
                  {"maxDataPoints", 10},
                  {"targets", {{{"target", "P-1:" + kWear}, {"refId", "A"}}, {{"target", "P-1:detection.ratio"}, {"refId", "B"}, {"hide", true}}}}};
  r = post("/api/v1/grafana/query", q);
  ASSERT_EQ(r->status, 200) << r->body;
  auto j = body(r);
  ASSERT_EQ(j.size(), 1u);  // the hidden target left out
  EXPECT_EQ(j[0]["target"], "P-1:" + kWear);
  EXPECT_EQ(j[0]["refId"], "A");
  const auto& dp = j[0]["datapoints"];
  ASSERT_LE(dp.size(), 10u);
  ASSERT_GE(dp.size(), 6u);
  double hi = 0;
  std::int64_t last_ms = 0;
  for (const auto& p : dp) {
    hi = std::max(hi, p[0].get<double>());
    EXPECT_GE(p[1].get<std::int64_t>(), last_ms);  // in time order
    last_ms = p[1].get<std::int64_t>();
  }
  EXPECT_NEAR(hi, 1.0 + 0.02 * 29 + 0.01, 1e-12);  // the peak survives the buckets
  EXPECT_GE(dp[0][1].get<std::int64_t>(), kT0 / 1'000'000);
  // Few enough points: each one as it is.
  auto few = q;
  few["maxDataPoints"] = 1000;
  j = body(post("/api/v1/grafana/query", few));
  EXPECT_EQ(j[0]["datapoints"].size(), 30u);
  EXPECT_EQ(j[0]["datapoints"][0][1], kT0 / 1'000'000);

  // Annotations: the alarm journal. P-1's wear alarm raised on day 25 and
  // acknowledged on day 26, in the range.
  const auto journal = [&](const std::string& pump, std::int64_t day, const std::vector<std::tuple<std::string, std::string, std::string, std::string>>& steps) {
    storage::AlarmChanges ch;
    ch.pump_id = pump;
    storage::AlarmRecord a;
    a.pump_id = pump;
    a.rule = "fault.impeller_seal_wear";
    a.severity = "high";
    a.state = "ack_active";
    a.active = a.acknowledged = true;
    a.raised_at = a.updated_at = storage::utc_from_ns(kT0 + day * kDayNs);
    a.run_id = pump + "/d" + std::to_string(day);
    a.message = "wear";
    ch.alarms.push_back(a);
    for (size_t i = 0; i < steps.size(); ++i) {
      storage::AlarmEvent e;
      std::tie(e.kind, e.from, e.to, e.by) = steps[i];
      e.time = detail::iso_ms(kT0 + (day + static_cast<std::int64_t>(i)) * kDayNs);
      e.comment = e.kind == "ack" ? "seen, renewal planned" : "";
      e.run_id = e.kind == "raise" ? a.run_id : "";
      ch.events.emplace_back(0, e);
    }
    h_->apply_alarm_changes(ch);
  };
  journal("P-1", 25, {{"raise", "normal", "unack_active", "server"}, {"ack", "unack_active", "ack_active", "ana"}});
  r = post("/api/v1/grafana/annotations", {{"range", q["range"]}, {"annotation", {{"name", "alarms"}, {"query", "P-1"}}}});
  ASSERT_EQ(r->status, 200) << r->body;
  j = body(r);
  ASSERT_EQ(j.size(), 2u) << j.dump();
  EXPECT_EQ(j[0]["time"], (kT0 + 25 * kDayNs) / 1'000'000);
  EXPECT_EQ(j[0]["title"], "P-1: fault.impeller_seal_wear");
  EXPECT_NE(j[0]["text"].get<std::string>().find("P-1/d25"), std::string::npos) << j[0];
  EXPECT_EQ(j[0]["annotation"]["name"], "alarms");
  EXPECT_NE(j[1]["text"].get<std::string>().find("by ana (seen, renewal planned)"), std::string::npos) << j[1];
  EXPECT_EQ(j[1]["tags"], json({"P-1", "fault.impeller_seal_wear", "ack", "high"}));
  // The range's end is inclusive to the millisecond; a narrower one keeps the raise only.
  json narrow = q["range"];
  narrow["to"] = storage::utc_from_ns(kT0 + 25 * kDayNs);
  EXPECT_EQ(body(post("/api/v1/grafana/annotations", {{"range", narrow}, {"annotation", {{"query", "P-1"}}}})).size(), 1u);

  // Bad bodies: named.
  const auto bad = [&](const json& b, int status, const std::string& what) {
    const auto res = post("/api/v1/grafana/query", b);
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, status) << res->body;
    EXPECT_NE(body(res)["error"].get<std::string>().find(what), std::string::npos) << res->body;
  };
  bad({{"targets", {{{"target", "P-1:no.such"}}}}}, 404, "no.such");
  bad({{"targets", {{{"target", "nocolon"}}}}}, 400, "targets[0].target");
  bad({{"targets", json::array()}, {"maxDataPoints", 0}}, 400, "maxDataPoints");
  bad({{"targets", json::array()}, {"range", {{"from", "soon"}}}}, 400, "range.from");
  bad(json::object(), 400, "targets");
  httplib::Client c("127.0.0.1", port_);
  const auto nojson = c.Post("/api/v1/grafana/query", "{", "application/json");
  EXPECT_EQ(nojson->status, 400);
}

TEST_F(TrendRest, GrafanaPostsNeedAViewerTokenLikeEveryRead) {
  wearing_pump();
  const std::string viewer = h_->add_token("grafana", storage::Role::viewer);
  start(false);
  const json q = {{"targets", {{{"target", "P-1:detection.ratio"}}}}};
  EXPECT_EQ(post("/api/v1/grafana/query", q)->status, 401);
  const auto r = post("/api/v1/grafana/query", q, viewer);
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(body(r)[0]["datapoints"].size(), 30u);
}

}  // namespace
}  // namespace ambdiag::server
