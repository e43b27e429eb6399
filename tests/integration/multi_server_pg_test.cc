// Several servers on one PostgreSQL database of the test cluster
// (multi_server_fixture.h, as multi_server_test on a file): the same kill -9
// and SIGSTOP of analysis workers, every run analysed once, events and REST
// the same on every server.
#include "multi_server_fixture.h"

namespace ambdiag::testing {
namespace {

class MultiServerPgTest : public MultiServerTest {
 protected:
  void SetUp() override {
    const auto loc = postgres_test_location();
    if (!loc) GTEST_SKIP() << "AMBDIAG_NO_POSTGRES=1: the PostgreSQL backend is not tested";
    db = *loc;
  }
};

TEST_F(MultiServerPgTest, AKilledAndAPausedWorkerLoseTheirJobsAndEveryRunIsAnalysedOnce) {
  run_scenario({6, 2.0, 2});
}

}  // namespace
}  // namespace ambdiag::testing
