// The end-to-end evidence of issue 22 in full (cluster_e2e_fixture.h): a
// dozen simulated pumps streaming into three servers on one PostgreSQL
// database; the ingest holder killed mid-run, an analysis worker killed
// mid-job, the then holder paused past its leases and woken, PostgreSQL
// restarted cleanly (-m fast) and then crashed (-m immediate) mid-stream.
#include "cluster_e2e_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(ClusterE2ETest, ADozenPumpsThroughEveryFaultLoseNothingAndAnalyseEveryRunOnce) {
  ClusterScenario sc;
  sc.agents = 12;
  sc.runs = 10;
  sc.worker_faults = true;
  sc.pg_restarts = {"fast", "immediate"};
  run_cluster(sc);
}

}  // namespace
}  // namespace ambdiag::testing
