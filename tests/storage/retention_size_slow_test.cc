// The file stays bounded under steady streaming with a size policy: 6 MiB
// runs as the agents stream them, 2.4 GB in all (labelled slow).
#include "retention_size.h"

namespace ambdiag::storage {
namespace {

TEST(RetentionSizeSlow, SixMegabyteRunsOfFourPumpsForAFewHundredRuns) {
  SteadyStream s;
  s.pumps = 4;
  s.run_frames = 786432;  // 6 MiB a run
  s.runs_per_pump = 100;
  s.runs_per_pump_kept = 6;
  s.sweep_every = 2;
  expect_bounded(stream_with_retention(s));
}

}  // namespace
}  // namespace ambdiag::storage
