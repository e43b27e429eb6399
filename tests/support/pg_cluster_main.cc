// ambdiag-test-pg start|stop [DIR] [durable]: the PostgreSQL cluster one
// ctest run shares (tests/support/pg_cluster.h), in the build's folder by
// default; `durable`: with fsync on, for benchmarks (docs/benchmarks.md).
// ambdiag-test-pg restart DIR fast|immediate: PgCluster::restart, for the
// test scripts (serve_restart_slow_test.sh).
// Without PostgreSQL (or with AMBDIAG_NO_POSTGRES=1) `start` says so and
// succeeds: the SQLite half of the tests runs, and each PostgreSQL test
// fails saying what is missing (or is skipped, with AMBDIAG_NO_POSTGRES=1).
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "pg_cluster.h"

int main(int argc, char** argv) {
  const std::string cmd = argc > 1 ? argv[1] : "";
  const std::filesystem::path dir = argc > 2 ? argv[2] : ambdiag::testing::shared_pg_cluster_dir();
  try {
    if (cmd == "start") {
      if (const char* v = std::getenv("AMBDIAG_NO_POSTGRES"); v && std::string(v) == "1") {
        std::puts("AMBDIAG_NO_POSTGRES=1: no PostgreSQL cluster, the PostgreSQL tests are skipped");
        return 0;
      }
      const auto c = ambdiag::testing::PgCluster::start(dir, argc > 3 && std::string(argv[3]) == "durable");
      std::printf("PostgreSQL test cluster: %s\n", c.uri().c_str());
      return 0;
    }
    if (cmd == "stop") {
      ambdiag::testing::PgCluster::stop(dir);
      return 0;
    }
    if (cmd == "restart" && argc == 4) {
      ambdiag::testing::PgCluster::restart(dir, argv[3]);
      return 0;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ambdiag-test-pg %s: %s\n", cmd.c_str(), e.what());
    return cmd == "start" ? 0 : 1;  // start: each PostgreSQL test then fails with this message
  }
  std::fprintf(stderr, "usage: ambdiag-test-pg start|stop [DIR] | restart DIR fast|immediate\n");
  return 2;
}
