// The web UI's explain button in a real browser (web_ui_fixture.h), slow
// for the explain job itself (~15 s on 2 cores): an engineer signs in, runs
// explain on the worn-piston run and sees its report with the fit before
// and after and explain.svg.
#include "web_ui_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(WebUiTest, AnEngineerRunsExplainFromTheRunView) {
  require_browser();
  if (IsSkipped()) return;
  const std::string faulty_run = set_up_fleet();
  ASSERT_FALSE(faulty_run.empty());
  EXPECT_EQ(run_browser(faulty_run, "run,explain"), 0);
}

}  // namespace
}  // namespace ambdiag::testing
