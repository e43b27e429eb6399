// The web UI in a real browser (web_ui_fixture.h), the whole check (label
// slow): a healthy pump beside the worn one (the fleet tells them apart,
// the healthy one ok), every view and the acknowledge, and the explain
// button (the job itself ~15 s on 2 cores): an engineer runs explain on the
// worn-piston run and sees its report with the fit before and after and
// explain.svg.
#include "web_ui_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(WebUiTest, AHealthyAndAFaultyPumpAndExplainFromTheRunView) {
  require_browser();
  if (IsSkipped()) return;
  const std::string faulty_run = set_up_fleet(true);
  ASSERT_FALSE(faulty_run.empty());
  EXPECT_EQ(run_browser(faulty_run, "fleet,run,pump,explain", "slow"), 0);
}

}  // namespace
}  // namespace ambdiag::testing
