// Several servers on one SQLite file (multi_server_fixture.h), longer:
// twelve runs, a 5 s lease (closer to the default 10 s).
#include "multi_server_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(MultiServerTest, TwelveRunsAKilledAndAPausedWorkerWithAFiveSecondLease) { run_scenario({12, 5.0, 2}); }

}  // namespace
}  // namespace ambdiag::testing
