// Job leases (schema v8): a claim holds its job until its lease ends, the
// worker renews it, an expired lease is queued again by any connection (or
// failed after the last attempt), and an attempt whose lease expired never
// stores anything, even before anyone requeued or claimed the job.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

using namespace std::chrono_literals;

class JobLeaseTest : public ambdiag::testing::BackendTest {};
AMBDIAG_ON_BOTH_BACKENDS(JobLeaseTest);

std::int64_t enqueue(Historian& h, const std::string& run_id) {
  return h.enqueue_job(JobKey{"analysis", "P-1", run_id, 1, 0}).first;
}

// Milliseconds from now to an ISO 8601 time of the historian (3 decimals, Z).
double ms_until(const std::string& iso) {
  std::tm tm{};
  int ms = 0;
  EXPECT_EQ(std::sscanf(iso.c_str(), "%d-%d-%dT%d:%d:%d.%dZ", &tm.tm_year, &tm.tm_mon, &tm.tm_mday, &tm.tm_hour,
                        &tm.tm_min, &tm.tm_sec, &ms),
            7)
      << iso;
  tm.tm_year -= 1900;
  tm.tm_mon -= 1;
  const auto t = std::chrono::system_clock::from_time_t(timegm(&tm)) + std::chrono::milliseconds(ms);
  return std::chrono::duration<double, std::milli>(t - std::chrono::system_clock::now()).count();
}

TEST_P(JobLeaseTest, AClaimHoldsItsJobForTheLeaseAndARenewalExtendsIt) {
  auto h = Historian::open(location());
  const auto id = enqueue(h, "r1");
  const auto job = h.claim_job("host:1/worker-0", {}, 2000ms);
  ASSERT_TRUE(job);
  ASSERT_TRUE(job->lease_expires_at);
  EXPECT_NEAR(ms_until(*job->lease_expires_at), 2000, 500);
  EXPECT_EQ(job->worker, "host:1/worker-0");
  ASSERT_TRUE(h.renew_job_lease(id, job->attempts, 8000ms));
  EXPECT_NEAR(ms_until(*h.find_job(id)->lease_expires_at), 8000, 500);
  EXPECT_FALSE(h.renew_job_lease(id, job->attempts + 1, 8000ms));  // no such attempt
  // A live lease is not requeued, from this connection or another one.
  EXPECT_EQ(h.requeue_expired_jobs().requeued, 0);
  auto other = Historian::open(location());
  EXPECT_EQ(other.requeue_expired_jobs().requeued, 0);
  EXPECT_EQ(h.find_job(id)->status, JobStatus::running);
  // Done: the lease is gone with the attempt.
  ASSERT_TRUE(h.finish_job(id, job->attempts, "{}"));
  EXPECT_FALSE(h.find_job(id)->lease_expires_at);
  EXPECT_FALSE(h.renew_job_lease(id, job->attempts));
}

TEST_P(JobLeaseTest, RenewalsKeepAJobPastManyLeases) {
  auto h = Historian::open(location());
  const auto id = enqueue(h, "r1");
  // A lease of 400 ms renewed every 40 ms (and a requeue), 30 times: three
  // leases long; the slack (360 ms a renewal) holds on a loaded machine,
  // where a 150 ms lease once lapsed between two renewals (CI beside a build).
  const auto job = h.claim_job("w", {}, 400ms);
  auto reaper = Historian::open(location());  // another process' requeue, every few ms
  for (int i = 0; i < 30; ++i) {
    std::this_thread::sleep_for(40ms);
    ASSERT_TRUE(h.renew_job_lease(id, job->attempts, 400ms)) << i;
    EXPECT_EQ(reaper.requeue_expired_jobs().requeued, 0) << i;
  }
  EXPECT_TRUE(h.set_job_progress(id, job->attempts, 0.5));
  EXPECT_TRUE(h.finish_job(id, job->attempts, R"({"ok": true})"));
  EXPECT_EQ(h.find_job(id)->attempts, 1);
}

// The worker was killed or paused: its lease runs out. From then on it
// holds nothing, even while the job still shows `running` with its number,
// and the next requeue gives the job to another worker.
TEST_P(JobLeaseTest, AnExpiredAttemptIsRefusedBeforeAndAfterTheRequeue) {
  auto h = Historian::open(location());
  const auto id = enqueue(h, "r1");
  const auto first = h.claim_job("paused", {}, 100ms);
  ASSERT_TRUE(first);
  EXPECT_TRUE(h.set_job_progress(id, 1, 0.3));
  std::this_thread::sleep_for(150ms);
  // Nobody requeued it yet: still running attempt 1, but its lease is over.
  EXPECT_EQ(h.find_job(id)->status, JobStatus::running);
  EXPECT_FALSE(h.renew_job_lease(id, 1));
  EXPECT_FALSE(h.set_job_progress(id, 1, 0.9));
  EXPECT_FALSE(h.finish_job(id, 1, R"({"from": "paused"})", {{"a.svg", "image/svg+xml", "<svg/>"}}));
  EXPECT_FALSE(h.fail_job(id, 1, "late"));
  EXPECT_FALSE(h.release_job(id, 1));
  EXPECT_FALSE(h.find_job(id)->result_json);
  EXPECT_TRUE(h.list_artifacts(id).empty());

  auto other = Historian::open(location());  // another analysis process
  const auto r = other.requeue_expired_jobs();
  EXPECT_EQ(r.requeued, 1);
  EXPECT_EQ(r.failed, 0);
  const auto queued = h.find_job(id);
  EXPECT_EQ(queued->status, JobStatus::queued);
  EXPECT_EQ(queued->attempts, 1);  // kept: the next claim is attempt 2
  EXPECT_FALSE(queued->lease_expires_at);
  EXPECT_EQ(queued->worker, "");
  const auto second = other.claim_job("taker", {}, 5000ms);
  ASSERT_TRUE(second);
  EXPECT_EQ(second->attempts, 2);
  // The paused worker resumes: its late result is still refused.
  EXPECT_FALSE(h.finish_job(id, 1, R"({"from": "paused"})"));
  EXPECT_TRUE(other.finish_job(id, 2, R"({"from": "taker"})"));
  const auto done = h.find_job(id);
  EXPECT_EQ(done->status, JobStatus::done);
  EXPECT_EQ(done->result_json, R"({"from": "taker"})");
  EXPECT_EQ(done->attempts, 2);
  EXPECT_EQ(h.requeue_expired_jobs().requeued, 0);
}

TEST_P(JobLeaseTest, AJobWhoseLeaseExpiresAtEachOfThreeAttemptsFails) {
  auto h = Historian::open(location());
  const auto poison = enqueue(h, "poison");
  for (int attempt = 1; attempt <= 3; ++attempt) {
    const auto claimed = h.claim_job("w" + std::to_string(attempt), {}, 30ms);
    ASSERT_TRUE(claimed);
    ASSERT_EQ(claimed->job_id, poison);
    std::this_thread::sleep_for(50ms);
    const auto r = h.requeue_expired_jobs(3);
    EXPECT_EQ(r.requeued, attempt < 3 ? 1 : 0) << attempt;
    EXPECT_EQ(r.failed, attempt < 3 ? 0 : 1) << attempt;
  }
  const auto failed = h.find_job(poison);
  EXPECT_EQ(failed->status, JobStatus::failed);
  EXPECT_EQ(failed->error, "gave up after 3 attempts: each lost its lease (its worker died or stalled)");
  EXPECT_FALSE(failed->lease_expires_at);
  EXPECT_FALSE(h.claim_job("w4"));
}

TEST_P(JobLeaseTest, AReleasedJobIsQueuedAgainAtOnceAndACancelledOneHoldsNothing) {
  auto h = Historian::open(location());
  const auto a = enqueue(h, "a"), b = enqueue(h, "b");
  const auto ja = h.claim_job("stopping", {}, 60000ms);
  ASSERT_EQ(ja->job_id, a);
  EXPECT_TRUE(h.release_job(a, ja->attempts));  // its process stops cleanly
  EXPECT_FALSE(h.release_job(a, ja->attempts));
  EXPECT_EQ(h.find_job(a)->status, JobStatus::queued);
  EXPECT_FALSE(h.find_job(a)->lease_expires_at);
  const auto again = h.claim_job("next");  // not a minute later
  ASSERT_EQ(again->job_id, a);
  EXPECT_EQ(again->attempts, 2);
  const auto jb = h.claim_job("w");
  ASSERT_EQ(jb->job_id, b);
  ASSERT_TRUE(h.cancel_job(b, "by an engineer"));
  EXPECT_FALSE(h.find_job(b)->lease_expires_at);
  EXPECT_FALSE(h.renew_job_lease(b, jb->attempts));
  EXPECT_FALSE(h.finish_job(b, jb->attempts, "{}"));
}

// A job left running by a program before schema v8 has no lease: its
// worker is gone with that program, so it counts as expired.
TEST_P(JobLeaseTest, ARunningJobWithoutALeaseCountsAsExpired) {
  const auto path = location();
  std::int64_t id = 0;
  {
    auto h = Historian::open(path);
    id = enqueue(h, "old");
    ASSERT_TRUE(h.claim_job("old-server"));
  }
  ASSERT_EQ(raw_error(path, "UPDATE jobs SET lease_expires_at = NULL"), "");
  auto h = Historian::open(path);
  EXPECT_FALSE(h.finish_job(id, 1, "{}"));
  EXPECT_EQ(h.requeue_expired_jobs().requeued, 1);
  EXPECT_EQ(h.claim_job("new-server")->attempts, 2);
}

}  // namespace
}  // namespace ambdiag::storage
