// The web UI in a real browser (issue 20; web_ui_fixture.h), the short
// default check on one pump whose piston wears: the fleet lists it with its
// fault, the run view draws the FRF, the pump shows its alarm, an operator
// acknowledges it in the page and the REST state changes, a new pump
// appears live. web_ui_slow_test.cc: a fleet with a healthy pump, explain.
#include "web_ui_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(WebUiTest, FleetPumpRunAndAlarmViewsWorkInAHeadlessBrowser) {
  require_browser();
  if (IsSkipped()) return;
  const std::string faulty_run = set_up_fleet(false);
  ASSERT_FALSE(faulty_run.empty());
  EXPECT_EQ(run_browser(faulty_run, "fleet,run,pump"), 0);
}

}  // namespace
}  // namespace ambdiag::testing
