// Real measurement no one here made: the amrotor magnetic-bearing rig
// (chirp, 8 accelerometers), FRF estimated here then fitted (about 7 s CPU).
#include "ambdiag/algorithms/estimation/frf_estimation.h"
#include "ambdiag/core/run_recording.h"
#include "evident_peaks.h"

namespace ambdiag {
namespace {

using real_data::expect_peaks_identified;

TEST(RationalFitRealData, AmrotorChirpEveryEvidentPeakIsAMode) {
  const FrfEstimate est = estimate_frf(read_run(testing::data_file("external/amrotor_mlps_sweep").string()));
  const RationalFitResult fit = fit_rational(est.frf);
  // The rig's authors report 16, 51, 59, 100, 162, 204 and 212 Hz; the
  // evident peaks are most of them.
  expect_peaks_identified(est.frf, fit, 5);
}

}  // namespace
}  // namespace ambdiag
