// The web UI in a real browser (issue 20; web_ui_fixture.h), the short
// default check on one pump whose piston wears, on a server with
// --anonymous-read: the views open read-only without a login and without
// action buttons; a viewer's token gets them disabled, naming the role
// needed; the fleet lists the pump with its fault, the run view draws the
// FRF (measured, model, fit), the pump shows its alarm, an operator
// acknowledges it in the page and the REST state changes, a new pump
// appears live. web_ui_slow_test.cc: the login page of a server without
// anonymous reads, a fleet with a healthy pump, explain.
#include "web_ui_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(WebUiTest, FleetPumpRunAndAlarmViewsWorkInAHeadlessBrowser) {
  require_browser();
  if (IsSkipped()) return;
  serve_options = {"--anonymous-read"};
  const std::string faulty_run = set_up_fleet(false);
  ASSERT_FALSE(faulty_run.empty());
  EXPECT_EQ(run_browser(faulty_run, "anonymous,viewer,fleet,run,pump"), 0);
}

}  // namespace
}  // namespace ambdiag::testing
