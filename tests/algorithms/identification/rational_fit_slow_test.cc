// The full Cramer-Rao comparison of the issue: 200 noise realisations.
#include "seven_mode.h"

namespace ambdiag {
namespace {

TEST(RationalFitSlow, SevenModeErrorsOver200RealisationsWithin1p3OfCramerRao) {
  seven_mode::expect_near_cramer_rao(200, 1.3, false);
}

}  // namespace
}  // namespace ambdiag

namespace ambdiag {
namespace {

// The same with the order chosen automatically in every realisation (the
// 7 modes must be found each time).
TEST(RationalFitSlow, SevenModeAutomaticOrderOver200RealisationsWithin1p3OfCramerRao) {
  seven_mode::expect_near_cramer_rao(200, 1.3, true);
}

}  // namespace
}  // namespace ambdiag
