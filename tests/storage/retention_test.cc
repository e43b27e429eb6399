// Retention (schema v9), on both backends: policies as JSON and per pump, the sweep by age
// and by size, what it never drops (reference runs, runs an open alarm or a
// queued or running job names, runs still receiving), FRFs after samples,
// monitoring, idempotency, the lease, a sweep stopped half way, and what a
// dropped run looks like to readers and writers; on PostgreSQL a day
// partition dropped whole, its few kept runs moved to sample_chunks_kept
// first (schema v10).
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <map>
#include <set>
#include <thread>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "retention_fixture.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

using nlohmann::json;

std::string db_path() { return (ambdiag::testing::scratch_dir() / "h.db").string(); }

// A retention test on each backend (Backends/RetentionTest.X/sqlite|postgres).
class RetentionTest : public ambdiag::testing::BackendTest {};
AMBDIAG_ON_BOTH_BACKENDS(RetentionTest);

using ambdiag::testing::raw_int;
using ambdiag::testing::raw_run;

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// A historian at `path` with one run, P-7/a, received 100 days ago.
Historian with_one_old_run(const std::string& path) {
  auto h = Historian::open(path);
  store_run(h, "P-7/a", "P-7", 500, 1);
  received_days_ago(path, "P-7/a", 100);
  return h;
}

// PostgreSQL: the UTC day `days_ago` days back ("2026-08-18") and its
// partition of sample_chunks, made as the historian names them.
struct PastDay {
  std::string date, partition;
};
PastDay make_day_partition(const std::string& location, int days_ago) {
  const std::string day = utc_days_ago(days_ago).substr(0, 10);
  const std::string name = "sample_chunks_d" + day.substr(0, 4) + day.substr(5, 2) + day.substr(8, 2);
  const std::string from = "CAST('" + day + " 00:00:00+00' AS timestamptz)";
  raw_run(location, "CREATE TABLE " + name + " PARTITION OF sample_chunks FOR VALUES FROM (" + from + ") TO (" + from +
                        " + interval '1 day')");
  return {day, name};
}

std::int64_t tables_named(const std::string& location, const std::string& name) {
  return raw_int(location, "SELECT count(*) FROM pg_class c JOIN pg_namespace n ON n.oid = c.relnamespace WHERE "
                           "n.nspname = current_schema() AND c.relname = '" + name + "'");
}

std::vector<std::string> dropped_ids(const SweepReport& r, const std::string& what = "samples") {
  std::vector<std::string> out;
  for (const auto& s : r.runs)
    if (s.what == what) out.push_back(s.run_id);
  return out;
}

// The runs whose samples the sweep dropped, by id.
std::vector<std::string> sorted_dropped_ids(const SweepReport& r) {
  auto ids = dropped_ids(r);
  std::sort(ids.begin(), ids.end());
  return ids;
}

// The run's samples read back as stored: byte for byte and by the checksum
// its end gave.
void expect_samples_intact(Historian& h, const StoredRun& run) {
  const std::string read = h.read_samples(run.run_id);
  EXPECT_EQ(read, ambdiag::testing::as_string(run.bytes)) << run.run_id;
  EXPECT_EQ(fnv1a64(read.data(), read.size()), h.find_run(run.run_id)->expected_checksum) << run.run_id;
}

// PostgreSQL: the run's chunks are in sample_chunks_kept (all of them) and
// it says so, or neither.
void expect_moved(const std::string& location, const std::string& run_id, bool moved) {
  const std::string id = "'" + run_id + "'";
  EXPECT_EQ(raw_int(location, "SELECT count(*) FROM sample_chunks_kept WHERE run_id = " + id),
            moved ? chunks_held(location, run_id) : 0)
      << run_id;
  EXPECT_EQ(raw_int(location, "SELECT count(*) FROM runs WHERE samples_kept_at IS NOT NULL AND run_id = " + id), moved ? 1 : 0)
      << run_id;
}

TEST(RetentionPolicy, KeysOverrideTheBaseAndNullKeepsForEver) {
  const RetentionPolicy base;  // the built-in defaults
  EXPECT_EQ(base.samples_days, 90.0);
  EXPECT_EQ(base.frf_days, 730.0);
  EXPECT_FALSE(base.samples_bytes);
  EXPECT_FALSE(base.monitoring_days);
  const auto p = retention_policy_from_json(json::parse(R"({"samples_days": 7.5, "samples_bytes": 1e9, "frf_days": null})"),
                                            base, "policy");
  EXPECT_EQ(p.samples_days, 7.5);
  EXPECT_EQ(p.samples_bytes, 1000000000);
  EXPECT_FALSE(p.frf_days);
  EXPECT_FALSE(p.monitoring_days);  // not given: the base's
  EXPECT_EQ(to_json(p), json::parse(R"({"samples_days": 7.5, "samples_bytes": 1000000000, "frf_days": null, "monitoring_days": null})"));
  EXPECT_EQ(to_json(retention_policy_from_json(json::object(), base, "policy")), to_json(base));
}

TEST(RetentionPolicy, EveryBadValueIsRefusedNamingItsKey) {
  const RetentionPolicy base;
  const auto error = [&](const char* text) { return error_of([&] { retention_policy_from_json(json::parse(text), base, "P"); }); };
  EXPECT_NE(error(R"({"sample_days": 3})").find("P: sample_days: unknown key (known: samples_days"), std::string::npos);
  EXPECT_NE(error(R"({"samples_days": -1})").find("P: samples_days: must be a number of days in 0..36500"), std::string::npos);
  EXPECT_NE(error(R"({"frf_days": "2y"})").find("P: frf_days:"), std::string::npos);
  EXPECT_NE(error(R"({"monitoring_days": 40000})").find("P: monitoring_days:"), std::string::npos);
  EXPECT_NE(error(R"({"samples_bytes": 1.5})").find("P: samples_bytes: must be a whole number"), std::string::npos);
  EXPECT_NE(error(R"({"samples_bytes": -4})").find("P: samples_bytes:"), std::string::npos);
  EXPECT_NE(error(R"({"samples_bytes": true})").find("P: samples_bytes:"), std::string::npos);
  EXPECT_NE(error("[1]").find("P: must be a JSON object"), std::string::npos);
}

TEST_P(RetentionTest, APumpsPolicyIsVersionedWithWhoAndWhen) {
  auto h = Historian::open(location());
  EXPECT_NE(error_of([&] { h.put_retention_policy("P-7", "{}", "erin"); }).find("unknown pump"), std::string::npos);
  store_run(h, "P-7/r1", "P-7", 10, 1);
  EXPECT_FALSE(h.find_retention_policy("P-7"));
  EXPECT_EQ(h.put_retention_policy("P-7", R"({"samples_days": 30})", "erin"), 1);
  EXPECT_EQ(h.put_retention_policy("P-7", R"({"samples_bytes": 5000000, "frf_days": null})", "carl"), 2);
  // A bad one names the key and stores nothing.
  EXPECT_NE(error_of([&] { h.put_retention_policy("P-7", R"({"samples_days": "x"})", "erin"); }).find("samples_days"),
            std::string::npos);
  EXPECT_NE(error_of([&] { h.put_retention_policy("P-7", "{nope", "erin"); }).find("not JSON"), std::string::npos);
  const auto list = h.list_retention_policies("P-7");
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0].created_by, "erin");
  EXPECT_EQ(json::parse(list[0].policy_json), json::parse(R"({"samples_days": 30})"));
  EXPECT_FALSE(list[0].created_at.empty());
  EXPECT_EQ(h.find_retention_policy("P-7")->version, 2);
  // The newest over the defaults: samples_days from the defaults again.
  RetentionPolicy defaults;
  defaults.samples_days = 10;
  const auto p = h.effective_retention_policy("P-7", defaults);
  EXPECT_EQ(p.samples_days, 10.0);
  EXPECT_EQ(p.samples_bytes, 5000000);
  EXPECT_FALSE(p.frf_days);
}

TEST(RetentionPolicy, AFileOfTheSchemaBeforeRetentionGetsItWithEveryRunHeld) {
  const auto path = db_path();
  {
    auto h = Historian::open(path);
    store_run(h, "P-7/old", "P-7", 500, 1);
  }
  downgrade_schema(path, 8);
  ASSERT_EQ(raw_query_int(path, "PRAGMA user_version"), 8);
  auto h = Historian::open(path);
  EXPECT_EQ(raw_query_int(path, "PRAGMA user_version"), Historian::schema_version());
  EXPECT_EQ(samples_state(h, "P-7/old"), "held");
  EXPECT_EQ(h.read_samples("P-7/old").size(), 4000u);
  received_days_ago(path, "P-7/old", 100);
  EXPECT_EQ(h.sweep_retention(samples_for_days(30)).samples_runs, 1);
}

TEST_P(RetentionTest, DropsTheSamplesOfRunsPastTheAgeAndKeepsTheRunsListed) {
  const auto path = location();
  auto h = Historian::open(path);
  const auto old_run = store_run(h, "P-7/old", "P-7", 3000, 1);
  const auto young = store_run(h, "P-7/young", "P-7", 3000, 2);
  received_days_ago(path, old_run.run_id, 31);
  received_days_ago(path, young.run_id, 29);
  const auto before = h.find_run(old_run.run_id);

  const auto r = h.sweep_retention(samples_for_days(30));
  EXPECT_EQ(dropped_ids(r), std::vector<std::string>{old_run.run_id});
  EXPECT_EQ(r.samples_runs, 1);
  EXPECT_EQ(r.samples_bytes, static_cast<std::int64_t>(old_run.bytes.size()));
  EXPECT_EQ(r.runs[0].reason, "age");
  EXPECT_EQ(r.transactions, 1);
  EXPECT_GT(r.longest_transaction_s, 0.0);
  EXPECT_EQ(chunks_held(path, old_run.run_id), 0);
  EXPECT_EQ(chunks_held(path, young.run_id), 3);

  // Still listed and complete, with what it had and when it was dropped.
  const auto after = h.find_run(old_run.run_id);
  ASSERT_TRUE(after);
  EXPECT_EQ(after->status, RunStatus::complete);
  EXPECT_EQ(after->samples_bytes(), before->samples_bytes());
  EXPECT_TRUE(after->samples_dropped_at);
  EXPECT_EQ(after->samples_dropped_bytes, static_cast<std::int64_t>(old_run.bytes.size()));
  EXPECT_EQ(after->header_json, before->header_json);
  EXPECT_EQ(h.list_runs("P-7").size(), 2u);
  EXPECT_FALSE(h.find_run(young.run_id)->samples_dropped_at);
  EXPECT_EQ(ambdiag::testing::as_string(young.bytes), h.read_samples(young.run_id));

  // Readers and writers are told, naming the run and the date.
  const std::string read = error_of([&] { h.read_samples(old_run.run_id); });
  EXPECT_NE(read.find("'P-7/old': its samples were dropped by retention at " + *after->samples_dropped_at), std::string::npos) << read;
  const auto chunks = ambdiag::testing::cut_chunks(old_run.bytes, 2, 1000);
  EXPECT_NE(error_of([&] { h.put_chunks(old_run.run_id, chunks); }).find("dropped by retention"), std::string::npos);
  EXPECT_EQ(chunks_held(path, old_run.run_id), 0);
  const auto usage = h.retention_usage("P-7");
  EXPECT_EQ(usage.runs_with_samples, 1);
  EXPECT_EQ(usage.samples_bytes_held, static_cast<std::int64_t>(young.bytes.size()));
  EXPECT_EQ(usage.runs_samples_dropped, 1);
  EXPECT_EQ(usage.samples_bytes_dropped, static_cast<std::int64_t>(old_run.bytes.size()));

  // Idempotent: the next sweep finds nothing.
  const auto again = h.sweep_retention(samples_for_days(30));
  EXPECT_TRUE(again.runs.empty());
  EXPECT_EQ(again.transactions, 0);
  if (!postgres()) {
    EXPECT_EQ(raw_integrity_check(path), "ok");
  }
}

TEST_P(RetentionTest, BySizeDropsTheOldestRunsUntilThePumpHoldsNoMore) {
  const auto path = location();
  auto h = Historian::open(path);
  std::vector<StoredRun> runs;
  for (int i = 0; i < 5; ++i) {  // 16 000 bytes each, received a day apart, oldest first
    runs.push_back(store_run(h, "P-7/r" + std::to_string(i), "P-7", 2000, static_cast<unsigned>(i)));
    received_days_ago(path, runs.back().run_id, 10 - i);
  }
  store_run(h, "P-8/r0", "P-8", 2000, 9);  // another pump: its own budget
  RetentionPolicy p;
  p.samples_days.reset();
  p.samples_bytes = 40000;  // 80 000 held: the three oldest go (32 000 left)
  const auto r = h.sweep_retention(p);
  EXPECT_EQ(dropped_ids(r), (std::vector<std::string>{"P-7/r0", "P-7/r1", "P-7/r2"}));
  for (const auto& s : r.runs) EXPECT_EQ(s.reason, "size");
  EXPECT_EQ(h.retention_usage("P-7").samples_bytes_held, 32000);
  EXPECT_EQ(samples_state(h, "P-8/r0"), "held");
  EXPECT_TRUE(h.sweep_retention(p).runs.empty());
}

TEST_P(RetentionTest, AgeAndSizeTogetherAndAPumpsOwnPolicyOverTheDefaults) {
  const auto path = location();
  auto h = Historian::open(path);
  for (int i = 0; i < 4; ++i) {
    store_run(h, "P-7/r" + std::to_string(i), "P-7", 2000, static_cast<unsigned>(i));
    received_days_ago(path, "P-7/r" + std::to_string(i), 10 - i);  // 10, 9, 8, 7 days
    store_run(h, "P-8/r" + std::to_string(i), "P-8", 2000, static_cast<unsigned>(i));
    received_days_ago(path, "P-8/r" + std::to_string(i), 10 - i);
  }
  // Defaults: 9.5 days. P-8 keeps 100 days but at most 2 runs' worth.
  h.put_retention_policy("P-8", R"({"samples_days": 100, "samples_bytes": 32000})", "erin");
  const auto r = h.sweep_retention(samples_for_days(9.5));
  EXPECT_EQ(dropped_ids(r), (std::vector<std::string>{"P-7/r0", "P-8/r0", "P-8/r1"}));
  EXPECT_EQ(r.pumps, 2);
}

TEST_P(RetentionTest, NeverDropsReferenceRunsRunsOfOpenAlarmsOrPendingJobsOrRunsStillReceiving) {
  const auto path = location();
  auto h = Historian::open(path);
  for (const char* id : {"P-7/ref1", "P-7/ref2", "P-7/alarm", "P-7/closed", "P-7/queued", "P-7/running", "P-7/done", "P-7/plain"})
    store_run(h, id, "P-7", 500, 1, 500, true);
  h.begin_run(run_header_from_json(ambdiag::testing::run_json_text("P-7/receiving", 2, "P-7")));
  h.put_chunks("P-7/receiving", ambdiag::testing::cut_chunks(ambdiag::testing::samples_bytes(500, 2, 3), 2, 500));
  h.put_reference("P-7", {"P-7/ref1", "P-7/ref2"}, "erin");
  h.put_reference("P-7", {"P-7/ref2", "P-7/plain"}, "erin");  // a newer version: ref1 stays needed by the old one
  h.enqueue_job({"analysis", "P-7", "P-7/queued", 1, 0});
  h.enqueue_job({"explain", "P-7", "P-7/running", 1, 0});
  h.enqueue_job({"analysis", "P-7", "P-7/done", 1, 0});
  for (int i = 0; i < 2; ++i) {  // claims oldest first: queued's job is claimed and finished, running's stays running
    const auto j = h.claim_job("w");
    if (j->key.run_id == "P-7/queued") {
      h.finish_job(j->job_id, j->attempts, "{}");
      h.enqueue_job({"analysis", "P-7", "P-7/queued", 2, 0});  // queued again (a new model)
    }
  }
  const auto j = h.claim_job("w");
  ASSERT_EQ(j->key.run_id, "P-7/done");
  h.finish_job(j->job_id, j->attempts, "{}");
  AlarmChanges c;
  c.pump_id = "P-7";
  for (const char* run : {"P-7/alarm", "P-7/closed"}) {
    AlarmRecord a;
    a.pump_id = "P-7";
    a.rule = std::string("rule-") + run;
    a.severity = "high";
    a.state = std::string(run) == "P-7/alarm" ? "ack_active" : "normal";
    a.active = a.state != "normal";
    a.acknowledged = true;
    a.raised_at = a.updated_at = "2026-11-26T10:00:00.000Z";
    a.run_id = run;
    a.message = "m";
    c.alarms.push_back(a);
  }
  h.apply_alarm_changes(c);
  for (const auto& r : h.list_runs("P-7")) received_days_ago(path, r.run_id, 400);

  const auto r = h.sweep_retention(samples_for_days(1));
  EXPECT_EQ(sorted_dropped_ids(r), (std::vector<std::string>{"P-7/closed", "P-7/done"}));
  for (const char* kept : {"P-7/ref1", "P-7/ref2", "P-7/plain", "P-7/alarm", "P-7/queued", "P-7/running", "P-7/receiving"})
    EXPECT_EQ(samples_state(h, kept), "held") << kept;
  EXPECT_EQ(chunks_held(path, "P-7/receiving"), 1);
}

TEST_P(RetentionTest, FrfsGoAfterTheSamplesOnlyTheAnalysesFilesAndKeepTheResults) {
  const auto path = location();
  auto h = Historian::open(path);
  store_run(h, "P-7/a", "P-7", 500, 1, 500, true);
  store_run(h, "P-7/b", "P-7", 500, 2, 500, true);
  const std::vector<JobArtifact> files = {{"frf.csv", "text/csv", std::string(3000, 'f')}, {"bode.svg", "image/svg+xml", "<svg/>"}};
  std::map<std::string, std::int64_t> analysis_of;
  for (const char* run : {"P-7/a", "P-7/b"}) {
    h.enqueue_job({"analysis", "P-7", run, 1, 0});
    const auto j = h.claim_job("w");
    h.finish_job(j->job_id, j->attempts, R"({"nrmse": 0.1})", files);
    analysis_of[run] = j->job_id;
  }
  h.enqueue_job({"explain", "P-7", "P-7/a", 1, 0});
  const auto ex = h.claim_job("w");
  h.finish_job(ex->job_id, ex->attempts, "{}", {{"improved_model.json", "application/json", "{}"}});
  received_days_ago(path, "P-7/a", 40);
  received_days_ago(path, "P-7/b", 40);

  RetentionPolicy p = samples_for_days(30);
  p.frf_days = 35;
  h.put_retention_policy("P-7", R"({"samples_days": 45})", "erin");  // b's pump keeps samples longer...
  auto r = h.sweep_retention(p);
  EXPECT_TRUE(r.runs.empty()) << "FRFs are not dropped while the samples are held";
  h.put_retention_policy("P-7", "{}", "erin");  // back to the defaults
  r = h.sweep_retention(p);
  EXPECT_EQ(dropped_ids(r, "samples").size(), 2u);
  EXPECT_EQ(dropped_ids(r, "frf").size(), 2u);
  EXPECT_EQ(r.frf_bytes, 2 * static_cast<std::int64_t>(3000 + 6));
  for (const char* run : {"P-7/a", "P-7/b"}) {
    EXPECT_TRUE(h.list_artifacts(analysis_of[run]).empty()) << run;
    EXPECT_EQ(h.find_job(analysis_of[run])->result_json, R"({"nrmse": 0.1})") << "the result is kept";
    const auto info = h.find_run(run);
    EXPECT_TRUE(info->frf_dropped_at);
    EXPECT_EQ(info->frf_dropped_bytes, 3006);
  }
  EXPECT_TRUE(h.find_artifact(ex->job_id, "improved_model.json")) << "an explain job's files are kept";
  EXPECT_TRUE(h.sweep_retention(p).runs.empty());
}

TEST_P(RetentionTest, AReferenceNeedsAnFrfOnceTheSamplesAreGone) {
  const auto path = location();
  auto h = Historian::open(path);
  store_run(h, "P-7/a", "P-7", 500, 1, 500, true);
  store_run(h, "P-7/b", "P-7", 500, 2, 500, true);
  store_run(h, "P-7/c", "P-7", 500, 3, 500, true);
  h.enqueue_job({"analysis", "P-7", "P-7/a", 1, 0});
  const auto j = h.claim_job("w");
  h.finish_job(j->job_id, j->attempts, "{}", {{"frf.csv", "text/csv", "f"}});
  for (const char* run : {"P-7/a", "P-7/b"}) received_days_ago(path, run, 100);
  EXPECT_EQ(h.sweep_retention(samples_for_days(30)).samples_runs, 2);
  // a kept its FRF: it may be a reference run; b did not.
  const std::string e = error_of([&] { h.put_reference("P-7", {"P-7/c", "P-7/b"}, "erin"); });
  EXPECT_NE(e.find("run 'P-7/b': its samples were dropped by retention at"), std::string::npos) << e;
  EXPECT_NE(e.find("no analysis of it kept its FRF"), std::string::npos) << e;
  EXPECT_EQ(h.put_reference("P-7", {"P-7/c", "P-7/a"}, "erin"), 1);
}

TEST_P(RetentionTest, MonitoringSnapshotsOlderThanTheirDaysInBatches) {
  auto h = Historian::open(location());
  const auto now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  std::vector<MonitoringSnapshot> snaps;
  for (int i = 0; i < 50; ++i) {  // one every hour for 50 hours back
    MonitoringSnapshot s;
    s.pump_id = "P-7";
    s.time_ns = now_ns - static_cast<std::int64_t>(i) * 3600'000'000'000;
    s.speed_rpm = 3000;
    snaps.push_back(s);
  }
  h.put_monitoring(snaps);
  RetentionPolicy p = samples_for_days(30);
  p.monitoring_days = 1.0 - 1e-6;  // the 24 of the last 24 hours stay (0 h .. 23 h)
  SweepOptions opt;
  opt.max_monitoring_rows_per_transaction = 7;
  opt.dry_run = true;
  EXPECT_EQ(h.sweep_retention(p, opt).monitoring_rows, 26);
  EXPECT_EQ(h.list_monitoring("P-7", 0, 100).size(), 50u) << "a dry run changes nothing";
  opt.dry_run = false;
  const auto r = h.sweep_retention(p, opt);
  EXPECT_EQ(r.monitoring_rows, 26);
  EXPECT_EQ(r.transactions, 4);  // 7 + 7 + 7 + 5
  const auto left = h.list_monitoring("P-7", 0, 100);
  ASSERT_EQ(left.size(), 24u);
  EXPECT_EQ(left.front().time_ns, now_ns - 23 * 3600'000'000'000);
}

TEST_P(RetentionTest, ADryRunReportsWhatTheSweepThenDrops) {
  const auto path = location();
  auto h = Historian::open(path);
  for (int i = 0; i < 4; ++i) {
    store_run(h, "P-7/r" + std::to_string(i), "P-7", 1000, static_cast<unsigned>(i), 1000, true);
    received_days_ago(path, "P-7/r" + std::to_string(i), 50.0 - 10 * i);  // 50, 40, 30, 20 days
  }
  RetentionPolicy p = samples_for_days(25);
  p.frf_days = 45;
  SweepOptions dry;
  dry.dry_run = true;
  const auto plan = h.sweep_retention(p, dry);
  EXPECT_EQ(dropped_ids(plan), (std::vector<std::string>{"P-7/r0", "P-7/r1", "P-7/r2"}));
  EXPECT_EQ(dropped_ids(plan, "frf"), std::vector<std::string>{"P-7/r0"});
  EXPECT_EQ(plan.transactions, 0);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(samples_state(h, "P-7/r" + std::to_string(i)), "held");
  // A dry run reads on a read-only connection too.
  auto reader = Historian::open(path, Historian::Mode::read);
  const auto read_plan = reader.sweep_retention(p, dry);
  EXPECT_EQ(dropped_ids(read_plan), dropped_ids(plan));
  EXPECT_EQ(read_plan.samples_bytes, plan.samples_bytes);

  const auto done = h.sweep_retention(p);
  EXPECT_EQ(dropped_ids(done), dropped_ids(plan));
  EXPECT_EQ(dropped_ids(done, "frf"), dropped_ids(plan, "frf"));
  EXPECT_EQ(done.samples_bytes, plan.samples_bytes);
}

TEST_P(RetentionTest, ALargeRunGoesInBoundedTransactionsAndAStoppedDropIsFinishedByTheNextSweep) {
  const auto path = location();
  auto h = Historian::open(path);
  const auto run = store_run(h, "P-7/big", "P-7", 10000, 4, 1000);  // 10 chunks of 8000 bytes
  received_days_ago(path, run.run_id, 100);
  SweepOptions opt;
  opt.max_bytes_per_transaction = 20000;  // two chunks a transaction
  int commits = 0;
  opt.after_commit = [&] { ++commits; };
  opt.stop = [&] { return commits >= 2; };  // after the second transaction
  auto r = h.sweep_retention(samples_for_days(30), opt);
  EXPECT_TRUE(r.stopped);
  EXPECT_EQ(r.samples_bytes, 32000);
  EXPECT_EQ(chunks_held(path, run.run_id), 6);
  // Half way it already reads as dropped: no reader sees a part of it.
  EXPECT_EQ(samples_state(h, run.run_id), "dropped");
  EXPECT_NE(error_of([&] { h.read_samples(run.run_id); }).find("dropped by retention"), std::string::npos);
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM runs WHERE samples_state = 'dropping'"), 1);

  opt.stop = nullptr;
  r = h.sweep_retention(samples_for_days(30), opt);
  ASSERT_EQ(r.runs.size(), 1u);
  EXPECT_EQ(r.runs[0].reason, "interrupted");
  EXPECT_EQ(r.runs[0].bytes, 48000);
  EXPECT_EQ(r.transactions, 3);
  EXPECT_LE(r.longest_transaction_s, r.transactions_s);
  EXPECT_EQ(chunks_held(path, run.run_id), 0);
  EXPECT_EQ(h.find_run(run.run_id)->samples_dropped_bytes, 80000);
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM runs WHERE samples_state = 'dropped'"), 1);
}

TEST_P(RetentionTest, TheLeaseKeepsASecondSweepOutUntilItIsReleasedOrExpires) {
  const auto path = location();
  auto h = with_one_old_run(path);
  auto other = Historian::open(path);
  // Another sweep holds the lease (a sweep of another process, running).
  raw_run(path, "INSERT INTO retention_lease VALUES ('sweep', 'other@host', '" + utc_days_ago(-1.0 / 24) + "')");
  auto r = h.sweep_retention(samples_for_days(30));
  EXPECT_NE(r.skipped.find("another sweep holds the retention lease: other@host until"), std::string::npos) << r.skipped;
  EXPECT_EQ(samples_state(h, "P-7/a"), "held");
  // Expired (the other died): taken over.
  raw_run(path, "UPDATE retention_lease SET expires_at = '" + utc_days_ago(1.0 / 24) + "'");
  r = h.sweep_retention(samples_for_days(30));
  EXPECT_TRUE(r.skipped.empty());
  EXPECT_EQ(r.samples_runs, 1);
  // Released at the end: the next sweep of anyone runs.
  EXPECT_TRUE(other.sweep_retention(samples_for_days(30)).skipped.empty());
}

TEST_P(RetentionTest, TwoConnectionsSweepingAtOnceDropEachRunOnce) {
  const auto path = location();
  {
    auto h = Historian::open(path);
    for (int i = 0; i < 20; ++i) {
      store_run(h, "P-7/r" + std::to_string(i), "P-7", 500, static_cast<unsigned>(i));
      received_days_ago(path, "P-7/r" + std::to_string(i), 100);
    }
  }
  std::vector<SweepReport> reports(2);
  std::vector<std::thread> threads;
  for (int t = 0; t < 2; ++t)
    threads.emplace_back([&, t] {
      auto h = Historian::open(path);
      SweepOptions opt;
      opt.yield_between_transactions = false;
      reports[t] = h.sweep_retention(samples_for_days(30), opt);
    });
  for (auto& t : threads) t.join();
  std::set<std::string> seen;
  for (const auto& r : reports)
    for (const auto& id : dropped_ids(r)) EXPECT_TRUE(seen.insert(id).second) << id << " dropped twice";
  EXPECT_EQ(seen.size(), 20u) << reports[0].skipped << " / " << reports[1].skipped;
  EXPECT_EQ(reports[0].samples_bytes + reports[1].samples_bytes, 20 * 4000);
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM sample_chunks"), 0);
}

TEST_P(RetentionTest, AStoredPolicyThatDoesNotReadDropsNothingOfItsPump) {
  const auto path = location();
  auto h = with_one_old_run(path);
  raw_run(path, "INSERT INTO retention_policies VALUES ('P-7', 1, '{\"samples_days\": \"soon\"}', '2026-01-01T00:00:00.000Z', 'x')");
  const auto r = h.sweep_retention(samples_for_days(30));
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_NE(r.errors[0].find("samples_days"), std::string::npos) << r.errors[0];
  EXPECT_EQ(samples_state(h, "P-7/a"), "held");
}

TEST_P(RetentionTest, OnPostgreSQLADayPartitionWithoutAKeptRunIsDroppedWholeAndKeptRunsStream) {
  if (!postgres()) GTEST_SKIP() << "day partitions are PostgreSQL's";
  const auto& path = location();
  auto h = Historian::open(path);
  const auto [day_a, part_a] = make_day_partition(path, 100);
  const auto [day_b, part_b] = make_day_partition(path, 101);
  std::map<std::string, StoredRun> runs;
  // Day A: two plain runs of two pumps. Day B: a plain run, a reference
  // run and a run whose analysis is queued.
  runs["P-7/a1"] = store_run(h, "P-7/a1", "P-7", 3000, 1);
  runs["P-8/a2"] = store_run(h, "P-8/a2", "P-8", 2000, 2);
  for (const char* id : {"P-7/b1", "P-7/bref", "P-7/bjob"}) runs[id] = store_run(h, id, "P-7", 3000, 3, 1000, true);
  h.put_reference("P-7", {"P-7/bref"}, "erin");
  h.enqueue_job({"analysis", "P-7", "P-7/bjob", 1, 0});
  for (const char* id : {"P-7/a1", "P-8/a2"}) received_at(path, id, day_a + "T12:00:00.000Z");
  for (const char* id : {"P-7/b1", "P-7/bref", "P-7/bjob"}) received_at(path, id, day_b + "T06:00:00.000Z");
  ASSERT_EQ(raw_int(path, "SELECT count(*) FROM " + part_a), 5) << "3 + 2 chunks moved into day A's partition";

  const auto r = h.sweep_retention(samples_for_days(30));
  EXPECT_EQ(r.partitions, 1);
  EXPECT_EQ(tables_named(path, part_a), 0) << "day A's partition is gone";
  EXPECT_EQ(tables_named(path, part_b), 1) << "day B holds kept runs";
  EXPECT_EQ(sorted_dropped_ids(r), (std::vector<std::string>{"P-7/a1", "P-7/b1", "P-8/a2"}));
  EXPECT_EQ(r.samples_bytes, static_cast<std::int64_t>(runs["P-7/a1"].bytes.size() + runs["P-8/a2"].bytes.size() +
                                                       runs["P-7/b1"].bytes.size()));
  for (const char* id : {"P-7/a1", "P-8/a2", "P-7/b1"}) {
    const auto info = h.find_run(id);
    EXPECT_TRUE(info->samples_dropped_at) << id;
    EXPECT_EQ(info->samples_dropped_bytes, static_cast<std::int64_t>(runs[id].bytes.size())) << id;
    EXPECT_EQ(chunks_held(path, id), 0) << id;
  }
  // The kept runs of day B still stream, byte for byte.
  for (const char* id : {"P-7/bref", "P-7/bjob"}) {
    std::string streamed;
    h.stream_samples(id, [&](std::span<const std::uint8_t> b) {
      streamed.append(reinterpret_cast<const char*>(b.data()), b.size());
      return true;
    });
    EXPECT_EQ(streamed, ambdiag::testing::as_string(runs[id].bytes)) << id;
  }
  // Idempotent; and new runs still go in (today's partition).
  const auto again = h.sweep_retention(samples_for_days(30));
  EXPECT_TRUE(again.runs.empty());
  EXPECT_EQ(again.partitions, 0);
  const auto fresh = store_run(h, "P-7/new", "P-7", 1000, 9);
  EXPECT_EQ(ambdiag::testing::as_string(fresh.bytes), h.read_samples("P-7/new"));
}

// 12 runs of 24 000 bytes received on `day` at noon: p0..p8 of P-7
// (plain), P-7/ref (a reference run), P-7/alarm (an open alarm's) and
// P-9/forever (its pump keeps samples for ever). The 3 kept runs hold
// exactly a quarter of the day's bytes.
std::map<std::string, StoredRun> a_day_with_three_kept_runs(Historian& h, const std::string& location, const std::string& day) {
  std::map<std::string, StoredRun> runs;
  for (unsigned i = 0; i < 9; ++i) {
    const std::string id = "P-7/p" + std::to_string(i);
    runs[id] = store_run(h, id, "P-7", 3000, i);
  }
  runs["P-7/ref"] = store_run(h, "P-7/ref", "P-7", 3000, 20, 1000, true);
  runs["P-7/alarm"] = store_run(h, "P-7/alarm", "P-7", 3000, 21);
  runs["P-9/forever"] = store_run(h, "P-9/forever", "P-9", 3000, 22);
  h.put_reference("P-7", {"P-7/ref"}, "erin");
  AlarmChanges c;
  c.pump_id = "P-7";
  c.alarms.push_back(ambdiag::testing::open_alarm("P-7", "rule-a"));
  c.alarms.back().run_id = "P-7/alarm";
  h.apply_alarm_changes(c);
  h.put_retention_policy("P-9", R"({"samples_days": null})", "erin");
  for (const auto& [id, run] : runs) received_at(location, id, day + "T12:00:00.000Z");
  return runs;
}

std::vector<std::string> plain_runs(int n) {
  std::vector<std::string> ids;
  for (int i = 0; i < n; ++i) ids.push_back("P-7/p" + std::to_string(i));
  return ids;
}

TEST_P(RetentionTest, OnPostgreSQLADaysFewKeptRunsMoveOutAndTheDayIsDroppedWhole) {
  if (!postgres()) GTEST_SKIP() << "day partitions are PostgreSQL's";
  const auto& path = location();
  auto h = Historian::open(path);
  const auto [day, part] = make_day_partition(path, 100);
  auto runs = a_day_with_three_kept_runs(h, path, day);
  ASSERT_EQ(raw_int(path, "SELECT count(*) FROM " + part), 36);

  const auto r = h.sweep_retention(samples_for_days(30));
  EXPECT_EQ(r.partitions, 1);
  EXPECT_EQ(tables_named(path, part), 0) << "the day went whole";
  EXPECT_EQ(r.moved_runs, 3);
  EXPECT_EQ(r.moved_bytes, 3 * 24000);
  EXPECT_EQ(sorted_dropped_ids(r), plain_runs(9)) << "only the plain runs are marked dropped";
  EXPECT_EQ(r.samples_bytes, 9 * 24000);
  for (const auto& id : plain_runs(9)) {
    EXPECT_EQ(h.find_run(id)->samples_dropped_bytes, 24000) << id;
    expect_moved(path, id, false);
  }
  for (const char* id : {"P-7/ref", "P-7/alarm", "P-9/forever"}) {
    EXPECT_EQ(samples_state(h, id), "held") << id;
    expect_moved(path, id, true);
    expect_samples_intact(h, runs[id]);
  }
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM sample_chunks_kept"), 9);

  // An agent re-sending a moved run: the same chunks are duplicates, other
  // bytes are refused, nothing lands anywhere else.
  const auto& ref = runs["P-7/ref"];
  const auto again = h.put_chunks(ref.run_id, ambdiag::testing::cut_chunks(ref.bytes, 2, 1000));
  EXPECT_EQ(again.duplicates, 3);
  EXPECT_EQ(again.stored, 0);
  auto other = ref.bytes;
  other[5] ^= 0x40;
  const std::string refused = error_of([&] { h.put_chunks(ref.run_id, ambdiag::testing::cut_chunks(other, 2, 1000)); });
  EXPECT_NE(refused.find("chunk seq 0: already held with other frames or bytes"), std::string::npos) << refused;
  EXPECT_EQ(chunks_held(path, ref.run_id), 3);
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM sample_chunks_default"), 0);
  expect_samples_intact(h, ref);

  const auto idle = h.sweep_retention(samples_for_days(30));
  EXPECT_TRUE(idle.runs.empty());
  EXPECT_EQ(idle.partitions + idle.moved_runs, 0);

  // No call removes a reference version (each keeps its runs): its row goes
  // behind the historian's back. P-9 falls back to the 30 days. Those two
  // runs then go row by row out of the kept partition; the alarm's stays.
  raw_run(path, "DELETE FROM reference_runs WHERE run_id = 'P-7/ref'");
  h.put_retention_policy("P-9", "{}", "erin");
  const auto later = h.sweep_retention(samples_for_days(30));
  EXPECT_EQ(sorted_dropped_ids(later), (std::vector<std::string>{"P-7/ref", "P-9/forever"}));
  EXPECT_EQ(later.partitions, 0);
  EXPECT_EQ(later.samples_bytes, 2 * 24000);
  for (const char* id : {"P-7/ref", "P-9/forever"}) {
    EXPECT_EQ(chunks_held(path, id), 0) << id;
    EXPECT_EQ(h.find_run(id)->samples_dropped_bytes, 24000) << id;
  }
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM sample_chunks_kept"), 3);
  expect_samples_intact(h, runs["P-7/alarm"]);
}

TEST_P(RetentionTest, OnPostgreSQLADayWhoseKeptRunsHoldMoreThanAQuarterOrWithARunReceivingStays) {
  if (!postgres()) GTEST_SKIP() << "day partitions are PostgreSQL's";
  const auto& path = location();
  auto h = Historian::open(path);
  const auto [day_x, part_x] = make_day_partition(path, 100);
  const auto [day_y, part_y] = make_day_partition(path, 101);
  // Day X: 3 plain runs of 23 200 bytes and a reference run of 24 000: just
  // over a quarter kept. Day Y: 3 plain runs and one still receiving.
  std::map<std::string, StoredRun> runs;
  for (unsigned i = 0; i < 3; ++i) runs["P-7/x" + std::to_string(i)] = store_run(h, "P-7/x" + std::to_string(i), "P-7", 2900, i);
  runs["P-7/xref"] = store_run(h, "P-7/xref", "P-7", 3000, 9, 1000, true);
  h.put_reference("P-7", {"P-7/xref"}, "erin");
  for (unsigned i = 0; i < 3; ++i) runs["P-8/y" + std::to_string(i)] = store_run(h, "P-8/y" + std::to_string(i), "P-8", 3000, i);
  h.begin_run(run_header_from_json(ambdiag::testing::run_json_text("P-8/receiving", 2, "P-8")));
  h.put_chunks("P-8/receiving", ambdiag::testing::cut_chunks(ambdiag::testing::samples_bytes(500, 2, 3), 2, 500));
  for (const auto& [id, run] : runs) received_at(path, id, (id.starts_with("P-7/") ? day_x : day_y) + "T12:00:00.000Z");
  received_at(path, "P-8/receiving", day_y + "T12:00:00.000Z");

  const auto r = h.sweep_retention(samples_for_days(30));
  EXPECT_EQ(r.partitions, 0);
  EXPECT_EQ(r.moved_runs, 0);
  EXPECT_EQ(tables_named(path, part_x) + tables_named(path, part_y), 2);
  EXPECT_EQ(sorted_dropped_ids(r), (std::vector<std::string>{"P-7/x0", "P-7/x1", "P-7/x2", "P-8/y0", "P-8/y1", "P-8/y2"}))
      << "the days' other runs go row by row";
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM " + part_x), 3) << "the reference run's chunks stay in their day";
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM " + part_y), 1) << "the receiving run's";
  expect_moved(path, "P-7/xref", false);
  expect_samples_intact(h, runs["P-7/xref"]);
}

TEST_P(RetentionTest, OnPostgreSQLARunNeededOnceTheKeptRunsMovedKeepsTheDayForTheNextSweep) {
  if (!postgres()) GTEST_SKIP() << "day partitions are PostgreSQL's";
  const auto& path = location();
  auto h = Historian::open(path);
  const auto [day, part] = make_day_partition(path, 100);
  auto runs = a_day_with_three_kept_runs(h, path, day);
  // Right after the sweep's first commit (the first run moved), another
  // server queues an analysis of P-7/p0: the drop's check, made again under
  // its locks, sees it.
  auto other = Historian::open(path);
  SweepOptions opt;
  bool queued = false;
  opt.after_commit = [&] {
    if (queued) return;
    other.enqueue_job({"analysis", "P-7", "P-7/p0", 1, 0});
    queued = true;
  };
  const auto r = h.sweep_retention(samples_for_days(30), opt);
  EXPECT_EQ(r.partitions, 0);
  EXPECT_EQ(tables_named(path, part), 1) << "kept for the next sweep";
  EXPECT_EQ(r.moved_runs, 3);
  const auto rest = plain_runs(9);
  EXPECT_EQ(sorted_dropped_ids(r), std::vector<std::string>(rest.begin() + 1, rest.end())) << "the others went row by row";
  expect_moved(path, "P-7/p0", false);
  EXPECT_EQ(samples_state(h, "P-7/p0"), "held");
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM " + part), 3) << "only P-7/p0's chunks are left in the day";

  // Its job done, the next sweep drops the day whole, P-7/p0 with it; the
  // moved runs stay held.
  const auto job = h.claim_job("w");
  ASSERT_EQ(job->key.run_id, "P-7/p0");
  h.finish_job(job->job_id, job->attempts, "{}");
  const auto next = h.sweep_retention(samples_for_days(30));
  EXPECT_EQ(next.partitions, 1);
  EXPECT_EQ(next.moved_runs, 0);
  EXPECT_EQ(dropped_ids(next), std::vector<std::string>{"P-7/p0"});
  EXPECT_EQ(h.find_run("P-7/p0")->samples_dropped_bytes, 24000);
  EXPECT_EQ(tables_named(path, part), 0);
  for (const char* id : {"P-7/ref", "P-7/alarm", "P-9/forever"}) expect_samples_intact(h, runs[id]);
}

TEST_P(RetentionTest, OnPostgreSQLASchema9DatabaseGetsTheKeptPartition) {
  if (!postgres()) GTEST_SKIP() << "the kept partition is PostgreSQL's";
  const auto& path = location();
  StoredRun run;
  {
    auto h = Historian::open(path);
    run = store_run(h, "P-7/a", "P-7", 500, 1);
  }
  raw_run(path, "DROP TABLE sample_chunks_kept; ALTER TABLE runs DROP COLUMN samples_kept_at; UPDATE ambdiag_schema SET version = 9");
  auto h = Historian::open(path);
  EXPECT_EQ(raw_int(path, "SELECT version FROM ambdiag_schema"), Historian::schema_version());
  EXPECT_EQ(tables_named(path, "sample_chunks_kept"), 1);
  EXPECT_EQ(raw_int(path, "SELECT count(*) FROM runs WHERE samples_kept_at IS NULL"), 1);
  expect_samples_intact(h, run);
}

}  // namespace
}  // namespace ambdiag::storage
