// The job queue (schema v4): the key's idempotency, claim order and
// dependencies, attempt fencing, results with their files, requeue and
// cancel, and two connections claiming from one file at once.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <set>
#include <thread>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"
#include "sqlite_raw.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

std::string db_path() { return (ambdiag::testing::scratch_dir() / "h.db").string(); }

class HistorianJobsTest : public ambdiag::testing::BackendTest {};
AMBDIAG_ON_BOTH_BACKENDS(HistorianJobsTest);

JobKey analysis(const std::string& run_id, int model_version = 1, int reference_version = 0,
                const std::string& pump_id = "P-1") {
  return {"analysis", pump_id, run_id, model_version, reference_version};
}

std::int64_t enqueue(Historian& h, const JobKey& key, std::optional<std::int64_t> depends_on = std::nullopt) {
  const auto [id, created] = h.enqueue_job(key, "{}", depends_on);
  EXPECT_TRUE(created);
  return id;
}

// A filter (designated initializers would warn of the members left out).
JobFilter filter(std::optional<std::string> pump_id, std::optional<std::string> run_id = std::nullopt,
                 std::optional<std::string> kind = std::nullopt, std::optional<JobStatus> status = std::nullopt,
                 int limit = 1000) {
  JobFilter f;
  f.pump_id = std::move(pump_id);
  f.run_id = std::move(run_id);
  f.kind = std::move(kind);
  f.status = status;
  f.limit = limit;
  return f;
}

TEST_P(HistorianJobsTest, EnqueueIsIdempotentOnTheKey) {
  auto h = Historian::open(location());
  const auto [id, created] = h.enqueue_job(analysis("r1"), R"({"speed_rpm": 3000})");
  EXPECT_TRUE(created);
  const auto again = h.enqueue_job(analysis("r1"), R"({"other": true})");
  EXPECT_EQ(again, std::make_pair(id, false));
  // Any field of the key makes another job.
  std::set<std::int64_t> ids{id};
  for (const JobKey& k : {analysis("r2"), analysis("r1", 2), analysis("r1", 1, 1), analysis("r1", 1, 0, "P-2"),
                          JobKey{"explain", "P-1", "r1", 1, 0}, JobKey{"reference", "P-1", "", 0, 1}}) {
    const auto [other, made] = h.enqueue_job(k);
    EXPECT_TRUE(made) << k.kind << " " << k.run_id;
    EXPECT_TRUE(ids.insert(other).second);
  }
  // The first enqueue's params stay; the job is found by its key.
  const auto job = h.find_job(analysis("r1"));
  ASSERT_TRUE(job);
  EXPECT_EQ(job->job_id, id);
  EXPECT_EQ(job->params_json, R"({"speed_rpm": 3000})");
  EXPECT_EQ(job->status, JobStatus::queued);
  EXPECT_EQ(job->attempts, 0);
  EXPECT_FALSE(job->started_at);
  EXPECT_FALSE(h.find_job(analysis("r9")));
  EXPECT_FALSE(h.find_job(std::int64_t{9999}));
  // Still one job after it ran.
  const auto c = h.claim_job("w");
  ASSERT_TRUE(c);
  ASSERT_TRUE(h.finish_job(c->job_id, c->attempts, "{}"));
  EXPECT_EQ(h.enqueue_job(c->key), std::make_pair(c->job_id, false));
  EXPECT_EQ(h.count_jobs(JobStatus::queued), 6);
}

TEST_P(HistorianJobsTest, EnqueueRefusesAnUnknownDependencyAndAnEmptyKey) {
  auto h = Historian::open(location());
  EXPECT_THROW(h.enqueue_job(analysis("r1"), "{}", 42), InputError);
  EXPECT_THROW(h.enqueue_job({"", "P-1", "r1", 1, 0}), InputError);
  EXPECT_THROW(h.enqueue_job({"analysis", "", "r1", 1, 0}), InputError);
  EXPECT_EQ(h.list_jobs({}).size(), 0u);
}

TEST_P(HistorianJobsTest, ClaimTakesTheOldestQueuedJobOfTheWantedKinds) {
  auto h = Historian::open(location());
  const auto a = enqueue(h, analysis("r1"));
  const auto e = enqueue(h, {"explain", "P-1", "r1", 1, 0});
  const auto b = enqueue(h, analysis("r2"));

  const auto only_explain = h.claim_job("w-explain", {"explain"});
  ASSERT_TRUE(only_explain);
  EXPECT_EQ(only_explain->job_id, e);
  EXPECT_FALSE(h.claim_job("w-explain", {"explain"}));
  EXPECT_FALSE(h.claim_job("w", {"reference"}));

  const auto first = h.claim_job("w1");
  ASSERT_TRUE(first);
  EXPECT_EQ(first->job_id, a);
  EXPECT_EQ(first->status, JobStatus::running);
  EXPECT_EQ(first->attempts, 1);
  EXPECT_EQ(first->worker, "w1");
  EXPECT_EQ(first->progress, 0.0);
  EXPECT_TRUE(first->started_at);
  EXPECT_FALSE(first->finished_at);
  EXPECT_EQ(h.find_job(a)->status, JobStatus::running);
  const auto second = h.claim_job("w2", {"analysis", "explain"});
  ASSERT_TRUE(second);
  EXPECT_EQ(second->job_id, b);
  EXPECT_FALSE(h.claim_job("w3"));
  EXPECT_EQ(h.count_jobs(JobStatus::running), 3);
}

TEST_P(HistorianJobsTest, AJobWaitsForItsDependencyAndOthersGoAhead) {
  auto h = Historian::open(location());
  const auto ref = enqueue(h, {"reference", "P-1", "", 1, 1});
  const auto dependent = enqueue(h, analysis("r1", 1, 1), ref);
  const auto free = enqueue(h, analysis("r2", 1, 1));

  const auto c1 = h.claim_job("w");
  ASSERT_TRUE(c1);
  EXPECT_EQ(c1->job_id, ref);
  const auto c2 = h.claim_job("w");  // the dependent waits: its dependency is running
  ASSERT_TRUE(c2);
  EXPECT_EQ(c2->job_id, free);
  EXPECT_FALSE(h.claim_job("w"));
  EXPECT_EQ(h.find_job(dependent)->status, JobStatus::queued);
  EXPECT_EQ(h.find_job(dependent)->depends_on, ref);

  ASSERT_TRUE(h.finish_job(ref, c1->attempts, R"({"learnt": true})"));
  const auto c3 = h.claim_job("w");
  ASSERT_TRUE(c3);
  EXPECT_EQ(c3->job_id, dependent);
}

TEST_P(HistorianJobsTest, AJobWhoseDependencyFailedOrWasCancelledFailsWithTheReason) {
  auto h = Historian::open(location());
  const auto a = enqueue(h, {"reference", "P-1", "", 1, 1});
  const auto b = enqueue(h, analysis("r1", 1, 1), a);
  const auto c = enqueue(h, {"explain", "P-1", "r1", 1, 1}, b);  // a chain
  const auto d = enqueue(h, {"reference", "P-1", "", 1, 2});
  const auto e = enqueue(h, analysis("r1", 1, 2), d);

  const auto ca = h.claim_job("w");
  ASSERT_EQ(ca->job_id, a);
  ASSERT_TRUE(h.fail_job(a, ca->attempts, "no runs left"));
  ASSERT_TRUE(h.cancel_job(d, "superseded by reference 3"));
  EXPECT_FALSE(h.claim_job("w"));  // nothing runnable: b, c and e fail on the way

  const std::string b_error = "depends on job " + std::to_string(a) + ", which failed: no runs left";
  EXPECT_EQ(h.find_job(b)->status, JobStatus::failed);
  EXPECT_EQ(h.find_job(b)->error, b_error);
  EXPECT_TRUE(h.find_job(b)->finished_at);
  EXPECT_EQ(h.find_job(b)->attempts, 0);
  EXPECT_EQ(h.find_job(c)->status, JobStatus::failed);
  EXPECT_EQ(h.find_job(c)->error, "depends on job " + std::to_string(b) + ", which failed: " + b_error);
  EXPECT_EQ(h.find_job(e)->status, JobStatus::failed);
  EXPECT_EQ(h.find_job(e)->error,
            "depends on job " + std::to_string(d) + ", which was cancelled: superseded by reference 3");
  EXPECT_EQ(h.count_jobs(JobStatus::failed), 4);
}

TEST_P(HistorianJobsTest, OnlyTheAttemptThatHoldsTheJobStoresAResultAndOnlyOnce) {
  auto h = Historian::open(location());
  const auto id = enqueue(h, analysis("r1"));
  const auto first = h.claim_job("server-1");
  ASSERT_TRUE(first);
  ASSERT_EQ(first->attempts, 1);
  EXPECT_TRUE(h.set_job_progress(id, 1, 0.25));
  EXPECT_EQ(h.find_job(id)->progress, 0.25);
  EXPECT_FALSE(h.finish_job(id, 2, "{}"));  // no such attempt yet
  EXPECT_FALSE(h.finish_job(id + 1, 1, "{}"));  // no such job

  // The server restarts: the job is queued again and claimed anew.
  EXPECT_EQ(h.requeue_running_jobs(), 1);
  const auto requeued = h.find_job(id);
  EXPECT_EQ(requeued->status, JobStatus::queued);
  EXPECT_EQ(requeued->progress, 0.0);
  EXPECT_EQ(requeued->attempts, 1);
  EXPECT_FALSE(h.finish_job(id, 1, R"({"from": "attempt 1"})"));  // a queued job takes no result
  EXPECT_FALSE(h.set_job_progress(id, 1, 0.5));
  const auto second = h.claim_job("server-2");
  ASSERT_TRUE(second);
  EXPECT_EQ(second->attempts, 2);
  EXPECT_EQ(second->worker, "server-2");

  // The first worker comes back late: refused, nothing stored.
  EXPECT_FALSE(h.set_job_progress(id, 1, 0.9));
  EXPECT_FALSE(h.finish_job(id, 1, R"({"from": "attempt 1"})", {{"plot.svg", "image/svg+xml", "<svg>1</svg>"}}));
  EXPECT_FALSE(h.fail_job(id, 1, "late"));
  EXPECT_EQ(h.find_job(id)->status, JobStatus::running);
  EXPECT_FALSE(h.find_job(id)->result_json);
  EXPECT_TRUE(h.list_artifacts(id).empty());
  EXPECT_EQ(h.find_job(id)->progress, 0.0);

  EXPECT_TRUE(h.finish_job(id, 2, R"({"from": "attempt 2"})", {{"plot.svg", "image/svg+xml", "<svg>2</svg>"}}));
  // Twice, or a fail after it: refused, the first result stays.
  EXPECT_FALSE(h.finish_job(id, 2, R"({"from": "again"})", {{"plot.svg", "image/svg+xml", "<svg>again</svg>"}}));
  EXPECT_FALSE(h.fail_job(id, 2, "too late"));
  EXPECT_FALSE(h.set_job_progress(id, 2, 0.1));
  const auto done = h.find_job(id);
  EXPECT_EQ(done->status, JobStatus::done);
  EXPECT_EQ(done->result_json, R"({"from": "attempt 2"})");
  EXPECT_EQ(done->progress, 1.0);
  EXPECT_EQ(done->attempts, 2);
  EXPECT_FALSE(done->error);
  EXPECT_TRUE(done->finished_at);
  EXPECT_EQ(h.find_artifact(id, "plot.svg")->data, "<svg>2</svg>");
  EXPECT_EQ(h.requeue_running_jobs(), 0);  // a done job is not requeued
}

// A job running at every one of three server deaths is likely what kills
// the server: the third restart fails it, naming why, and the others go on.
TEST_P(HistorianJobsTest, AJobRunningAtThreeServerDeathsFailsInsteadOfAFourthClaim) {
  auto h = Historian::open(location());
  const auto poison = enqueue(h, analysis("poison"));
  for (int death = 1; death <= 3; ++death) {
    const auto claimed = h.claim_job("server-" + std::to_string(death));
    ASSERT_TRUE(claimed);
    ASSERT_EQ(claimed->job_id, poison);
    EXPECT_EQ(h.requeue_running_jobs(), death < 3 ? 1 : 0) << death;
  }
  const auto failed = h.find_job(poison);
  EXPECT_EQ(failed->status, JobStatus::failed);
  EXPECT_EQ(failed->attempts, 3);
  ASSERT_TRUE(failed->error);
  EXPECT_EQ(*failed->error, "gave up after 3 attempts: the server stopped during each");
  EXPECT_TRUE(failed->finished_at);
  const auto next = enqueue(h, analysis("next"));
  EXPECT_EQ(h.claim_job("server-4")->job_id, next);
}

TEST_P(HistorianJobsTest, ProgressIsClampedToZeroToOneAndNaNIsRefused) {
  auto h = Historian::open(location());
  const auto id = enqueue(h, analysis("r1"));
  const auto c = h.claim_job("w");
  EXPECT_TRUE(h.set_job_progress(id, c->attempts, 1.5));
  EXPECT_EQ(h.find_job(id)->progress, 1.0);
  EXPECT_TRUE(h.set_job_progress(id, c->attempts, -0.5));
  EXPECT_EQ(h.find_job(id)->progress, 0.0);
  EXPECT_THROW(h.set_job_progress(id, c->attempts, std::nan("")), InputError);
}

TEST_P(HistorianJobsTest, AFailedJobKeepsItsErrorAndIsNotClaimedAgain) {
  auto h = Historian::open(location());
  const auto id = enqueue(h, analysis("r1"));
  const auto c = h.claim_job("w");
  ASSERT_TRUE(h.fail_job(id, c->attempts, "fit did not converge"));
  const auto j = h.find_job(id);
  EXPECT_EQ(j->status, JobStatus::failed);
  EXPECT_EQ(j->error, "fit did not converge");
  EXPECT_TRUE(j->finished_at);
  EXPECT_FALSE(h.claim_job("w"));  // failed is final
}

TEST_P(HistorianJobsTest, TheFilesAreStoredWithTheResultOrNotAtAll) {
  const auto path = location();
  auto h = Historian::open(path);
  const auto id = enqueue(h, analysis("r1"));
  auto c = h.claim_job("w");
  std::string binary = "a\0b\xff";
  binary.push_back('\0');
  const std::vector<JobArtifact> files = {{"frf.csv", "text/csv", "f_hz,re\n1,2\n"},
                                          {"bode.svg", "image/svg+xml", "<svg/>"},
                                          {"raw.bin", "application/octet-stream", binary},
                                          {"empty.txt", "text/plain", ""}};
  // Two files of one name: refused before anything is written.
  EXPECT_THROW(h.finish_job(id, c->attempts, "{}", {files[0], files[0]}), InputError);
  EXPECT_THROW(h.finish_job(id, c->attempts, "{}", {{"", "text/plain", "x"}}), InputError);
  EXPECT_EQ(h.find_job(id)->status, JobStatus::running);

  // The database refuses the third file: the result and the first two go too.
  EXPECT_EQ(raw_error(path, postgres() ? "CREATE FUNCTION refuse_raw() RETURNS trigger LANGUAGE plpgsql AS $$ BEGIN "
                                         "IF NEW.name = 'raw.bin' THEN RAISE EXCEPTION 'refused by the test'; END IF; "
                                         "RETURN NEW; END $$; CREATE TRIGGER refuse_raw BEFORE INSERT ON job_artifacts "
                                         "FOR EACH ROW EXECUTE FUNCTION refuse_raw()"
                                       : "CREATE TRIGGER refuse_raw BEFORE INSERT ON job_artifacts WHEN NEW.name = "
                                         "'raw.bin' BEGIN SELECT RAISE(ABORT, 'refused by the test'); END;"),
            "");
  auto h2 = Historian::open(path);  // a new connection sees the trigger at once
  EXPECT_THROW(h2.finish_job(id, c->attempts, R"({"ok": true})", files), StorageError);
  EXPECT_EQ(h2.find_job(id)->status, JobStatus::running);
  EXPECT_FALSE(h2.find_job(id)->result_json);
  EXPECT_TRUE(h2.list_artifacts(id).empty());
  EXPECT_EQ(raw_error(path, postgres() ? "DROP TRIGGER refuse_raw ON job_artifacts" : "DROP TRIGGER refuse_raw"), "");

  EXPECT_TRUE(h.finish_job(id, c->attempts, R"({"ok": true})", files));
  EXPECT_EQ(h.list_artifacts(id), (std::vector<std::string>{"bode.svg", "empty.txt", "frf.csv", "raw.bin"}));
  for (const auto& f : files) {
    const auto a = h.find_artifact(id, f.name);
    ASSERT_TRUE(a) << f.name;
    EXPECT_EQ(a->content_type, f.content_type);
    EXPECT_EQ(a->data, f.data) << f.name;
  }
  EXPECT_FALSE(h.find_artifact(id, "nope.svg"));
  EXPECT_FALSE(h.find_artifact(id + 1, "frf.csv"));
}

TEST_P(HistorianJobsTest, RequeueTakesBackEveryRunningJobAndOnlyThose) {
  auto h = Historian::open(location());
  for (int i = 0; i < 5; ++i) enqueue(h, analysis("r" + std::to_string(i)));
  const auto c1 = h.claim_job("w"), c2 = h.claim_job("w"), c3 = h.claim_job("w");
  ASSERT_TRUE(h.finish_job(c3->job_id, c3->attempts, "{}"));
  EXPECT_EQ(h.requeue_running_jobs(), 2);
  EXPECT_EQ(h.count_jobs(JobStatus::queued), 4);
  EXPECT_EQ(h.count_jobs(JobStatus::running), 0);
  EXPECT_EQ(h.count_jobs(JobStatus::done), 1);
  EXPECT_EQ(h.find_job(c1->job_id)->worker, "");
  // They come back first: the claim order is the job order.
  EXPECT_EQ(h.claim_job("w")->job_id, c1->job_id);
  EXPECT_EQ(h.claim_job("w")->job_id, c2->job_id);
}

TEST_P(HistorianJobsTest, ANewVersionCancelsTheQueuedJobsOfOlderVersionsOnly) {
  auto h = Historian::open(location());
  const auto running = enqueue(h, analysis("r0", 1, 0));
  ASSERT_EQ(h.claim_job("w")->job_id, running);
  const auto old_model = enqueue(h, analysis("r1", 1, 1));
  const auto old_ref = enqueue(h, analysis("r2", 2, 0));
  const auto current = enqueue(h, analysis("r3", 2, 1));
  const auto newer = enqueue(h, analysis("r4", 3, 1));
  const auto other_kind = enqueue(h, {"explain", "P-1", "r1", 1, 0});
  const auto other_pump = enqueue(h, analysis("q1", 1, 0, "P-2"));

  EXPECT_EQ(h.cancel_superseded_jobs("P-1", "analysis", 2, 1), 2);
  for (const auto id : {old_model, old_ref}) {
    const auto j = h.find_job(id);
    EXPECT_EQ(j->status, JobStatus::cancelled) << id;
    EXPECT_EQ(j->error, "superseded by model version 2, reference version 1");
    EXPECT_TRUE(j->finished_at);
  }
  EXPECT_EQ(h.find_job(running)->status, JobStatus::running);  // running: its worker finishes it
  for (const auto id : {current, newer, other_kind, other_pump}) EXPECT_EQ(h.find_job(id)->status, JobStatus::queued) << id;
  EXPECT_EQ(h.cancel_superseded_jobs("P-1", "analysis", 2, 1), 0);
}

TEST_P(HistorianJobsTest, CancelTakesAQueuedOrRunningJobAndNothingElse) {
  auto h = Historian::open(location());
  const auto queued = enqueue(h, analysis("r1"));
  const auto running = enqueue(h, analysis("r2"));
  const auto done = enqueue(h, analysis("r3"));
  h.claim_job("w", {"none"});  // claims nothing
  ASSERT_TRUE(h.cancel_job(queued, "asked by alice"));
  const auto cr = h.claim_job("w");
  ASSERT_EQ(cr->job_id, running);
  const auto cd = h.claim_job("w");
  ASSERT_EQ(cd->job_id, done);
  ASSERT_TRUE(h.finish_job(done, cd->attempts, "{}"));

  EXPECT_TRUE(h.cancel_job(running, "asked by bob"));
  EXPECT_FALSE(h.finish_job(running, cr->attempts, "{}"));  // its worker's result is refused
  EXPECT_FALSE(h.cancel_job(done, "too late"));
  EXPECT_FALSE(h.cancel_job(queued, "again"));
  EXPECT_FALSE(h.cancel_job(9999, "unknown"));
  EXPECT_EQ(h.find_job(queued)->status, JobStatus::cancelled);
  EXPECT_EQ(h.find_job(queued)->error, "asked by alice");
  EXPECT_EQ(h.find_job(running)->status, JobStatus::cancelled);
  EXPECT_FALSE(h.find_job(running)->result_json);
  EXPECT_EQ(h.find_job(done)->status, JobStatus::done);
  EXPECT_FALSE(h.claim_job("w"));
}

TEST_P(HistorianJobsTest, ListsNewestFirstByPumpRunKindAndStatus) {
  auto h = Historian::open(location());
  const auto a = enqueue(h, analysis("r1"));
  const auto b = enqueue(h, {"explain", "P-1", "r1", 1, 0});
  const auto c = enqueue(h, analysis("r2"));
  const auto d = enqueue(h, analysis("q1", 1, 0, "P-2"));
  h.claim_job("w");  // a runs
  const auto ids = [](const std::vector<Job>& jobs) {
    std::vector<std::int64_t> v;
    for (const auto& j : jobs) v.push_back(j.job_id);
    return v;
  };
  EXPECT_EQ(ids(h.list_jobs({})), (std::vector<std::int64_t>{d, c, b, a}));
  EXPECT_EQ(ids(h.list_jobs(filter("P-1"))), (std::vector<std::int64_t>{c, b, a}));
  EXPECT_EQ(ids(h.list_jobs(filter(std::nullopt, "r1"))), (std::vector<std::int64_t>{b, a}));
  EXPECT_EQ(ids(h.list_jobs(filter(std::nullopt, "r1", "analysis"))), (std::vector<std::int64_t>{a}));
  EXPECT_EQ(ids(h.list_jobs(filter("P-1", std::nullopt, std::nullopt, JobStatus::queued))), (std::vector<std::int64_t>{c, b}));
  EXPECT_EQ(ids(h.list_jobs(filter("P-2", "r1"))), (std::vector<std::int64_t>{}));
  EXPECT_EQ(ids(h.list_jobs(filter(std::nullopt, std::nullopt, std::nullopt, JobStatus::running))), (std::vector<std::int64_t>{a}));
  EXPECT_EQ(ids(h.list_jobs(filter(std::nullopt, std::nullopt, std::nullopt, std::nullopt, 2))), (std::vector<std::int64_t>{d, c}));
  EXPECT_THROW(h.list_jobs(filter(std::nullopt, std::nullopt, std::nullopt, std::nullopt, 0)), InputError);
  EXPECT_EQ(h.count_jobs(JobStatus::queued), 3);
  EXPECT_EQ(h.count_jobs(JobStatus::cancelled), 0);
  const auto listed = h.list_jobs(filter(std::nullopt, "r1", "analysis"));
  EXPECT_EQ(listed[0].worker, "w");
  EXPECT_EQ(listed[0].key.model_version, 1);
}

TEST_P(HistorianJobsTest, JobCallsInsideAWriteBatchJoinItAndRollBackWithIt) {
  const auto path = location();
  auto h = Historian::open(path);
  const auto kept = enqueue(h, analysis("r0"));
  {
    auto batch = h.write_batch();
    h.begin_run(run_header_from_json(ambdiag::testing::run_json_text("P-1/r1", 2, "P-1")));
    const auto id = enqueue(h, analysis("P-1/r1"));
    const auto c = h.claim_job("w");
    ASSERT_EQ(c->job_id, kept);
    EXPECT_THROW(h.enqueue_job(analysis("x"), "{}", 777), InputError);  // refused alone, the batch goes on
    EXPECT_TRUE(h.finish_job(kept, c->attempts, "{}"));
    EXPECT_EQ(h.find_job(id)->status, JobStatus::queued);
    // Not committed: the batch rolls back as a whole.
  }
  EXPECT_EQ(h.find_job(kept)->status, JobStatus::queued);
  EXPECT_EQ(h.list_jobs({}).size(), 1u);
  {
    auto batch = h.write_batch();
    enqueue(h, analysis("P-1/r1"));
    batch.commit();
  }
  auto r = Historian::open(path, Historian::Mode::read);
  EXPECT_EQ(r.count_jobs(JobStatus::queued), 2);
}

TEST(HistorianJobs, AClaimFromAnotherConnectionWaitsForAnOpenBatchAndThenSucceeds) {
  const auto path = db_path();
  auto ingest = Historian::open(path);
  auto server = Historian::open(path);
  const auto id = enqueue(server, analysis("r1"));
  std::atomic<bool> claimed{false};
  std::optional<Job> got;
  std::thread worker;
  {
    auto batch = ingest.write_batch();  // holds the write lock until commit
    ingest.begin_run(run_header_from_json(ambdiag::testing::run_json_text("P-1/r1", 2, "P-1")));
    worker = std::thread([&] {
      got = server.claim_job("w");
      claimed = true;
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    EXPECT_FALSE(claimed);  // waiting for the lock, within the busy timeout
    batch.commit();
  }
  worker.join();
  ASSERT_TRUE(got);
  EXPECT_EQ(got->job_id, id);
  EXPECT_TRUE(ingest.find_run("P-1/r1"));
}

TEST_P(HistorianJobsTest, TwoConnectionsClaimingAtOnceNeverTakeTheSameJob) {
  const auto path = location();
  constexpr int kJobs = 200;
  {
    auto h = Historian::open(path);
    auto batch = h.write_batch();
    for (int i = 0; i < kJobs; ++i) enqueue(h, analysis("r" + std::to_string(i)));
    batch.commit();
  }
  std::vector<std::int64_t> claimed[2];
  std::atomic<int> ready{0};
  const auto work = [&](int w) {
    auto h = Historian::open(path);  // one connection per thread
    const std::string name = "worker-" + std::to_string(w);
    for (++ready; ready < 2;) std::this_thread::yield();  // both start together
    while (auto j = h.claim_job(name)) {
      claimed[w].push_back(j->job_id);
      // The analysis, outside any transaction. Without it one thread takes
      // every job: SQLite's busy handler backs off for milliseconds while
      // the other commits every 0.1 ms.
      std::this_thread::sleep_for(std::chrono::microseconds(500));
      EXPECT_TRUE(h.finish_job(j->job_id, j->attempts, R"({"by": ")" + name + R"("})"));
    }
  };
  std::thread t0(work, 0), t1(work, 1);
  t0.join();
  t1.join();

  std::map<std::int64_t, int> times;
  for (const auto& v : claimed)
    for (const auto id : v) ++times[id];
  EXPECT_EQ(times.size(), static_cast<size_t>(kJobs));
  for (const auto& [id, n] : times) EXPECT_EQ(n, 1) << "job " << id;
  EXPECT_GT(claimed[0].size(), 0u);  // both took part
  EXPECT_GT(claimed[1].size(), 0u);
  auto h = Historian::open(path, Historian::Mode::read);
  EXPECT_EQ(h.count_jobs(JobStatus::done), kJobs);
  for (const auto& j : h.list_jobs({})) {
    EXPECT_EQ(j.attempts, 1);
    EXPECT_EQ(j.result_json, R"({"by": ")" + j.worker + R"("})");
  }
}

}  // namespace
}  // namespace ambdiag::storage
