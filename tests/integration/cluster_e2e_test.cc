// The end-to-end check of issue 22, small (cluster_e2e_fixture.h): three
// servers on a PostgreSQL cluster of the test's own, three simulated pumps
// streaming; the ingest holder killed mid-run, PostgreSQL crashed and
// restarted (-m immediate: the harsher restart; it found a holder that
// died on the connection lost under its BEGIN) mid-stream; every run
// complete and analysed once, the survivors' REST and events the same.
#include "cluster_e2e_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(ClusterE2ETest, AKilledHolderAndARestartedDatabaseLoseNothingAndAnalyseEveryRunOnce) {
  ClusterScenario sc;
  sc.agents = 3;
  sc.runs = 3;
  sc.pg_restarts = {"immediate"};
  run_cluster(sc);
}

}  // namespace
}  // namespace ambdiag::testing
