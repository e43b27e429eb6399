// The web UI in a real browser (issue 20; web_ui_fixture.h): the fleet
// lists the pumps, the faulty one shows its fault and alarm, an operator
// acknowledges it in the page and the REST state changes, the run view
// draws the FRF, a new pump appears live.
#include "web_ui_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(WebUiTest, FleetPumpRunAndAlarmViewsWorkInAHeadlessBrowser) {
  require_browser();
  if (IsSkipped()) return;
  const std::string faulty_run = set_up_fleet();
  ASSERT_FALSE(faulty_run.empty());
  EXPECT_EQ(run_browser(faulty_run, "fleet,run,pump"), 0);
}

}  // namespace
}  // namespace ambdiag::testing
