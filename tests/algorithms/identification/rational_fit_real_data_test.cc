// Real measurement no one here made: pyuff's accelerance (no sigma).
#include "evident_peaks.h"

namespace ambdiag {
namespace {

using real_data::expect_peaks_identified;

TEST(RationalFitRealData, PyuffAccelerancePeaksAreModesWithoutSigma) {
  const FrfData frf = read_frf_csv(testing::data_file("external/pyuff_meas_point_1/frf.csv").string());
  const RationalFitResult fit = fit_rational(frf);
  EXPECT_FALSE(fit.report.sigma_from_data);
  expect_peaks_identified(frf, fit, 3);
}

}  // namespace
}  // namespace ambdiag
