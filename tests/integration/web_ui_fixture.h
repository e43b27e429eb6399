// The web UI's browser tests (issue 20): a real `ambdiag serve` with real
// agents (fleet_fixture.h: two simulated pumps, one whose balance piston
// wears), then web/tests/ui_test.mjs drives Debian's headless chromium
// through playwright-core against it. Screenshots go to
// build/web-screenshots/ (the slow test's to build/web-screenshots/slow/:
// both may run at once). web_ui_test.cc holds the default check (a server
// with --anonymous-read, and a viewer's token), web_ui_slow_test.cc the
// login page first and the explain job (label slow).
#pragma once

#include "fleet_fixture.h"

namespace ambdiag::testing {

class WebUiTest : public FleetTest {
 protected:
  std::string pumps_;  // the pumps streamed, as ui_test.mjs takes them
  // Skips (naming what is missing; the test returns on IsSkipped()) where node, chromium or web/node_modules
  // are not installed: deploy/install-deps.sh installs all three.
  void require_browser() {
    if (std::string(AMBDIAG_NODE).empty())
      GTEST_SKIP() << "node not found at configure time (deploy/install-deps.sh)";
    if (!fs::exists("/usr/bin/chromium") && !std::getenv("AMBDIAG_CHROMIUM"))
      GTEST_SKIP() << "no /usr/bin/chromium (deploy/install-deps.sh installs Debian's)";
    if (!fs::exists(fs::path(AMBDIAG_WEB_SOURCE) / "node_modules/playwright-core"))
      GTEST_SKIP() << "web/node_modules missing (deploy/install-deps.sh runs npm ci in web/)";
  }

  // Pumps of the reference machine: W-2's piston worn 1.5 x from its 4th
  // run, and with `healthy_too` W-1, healthy; then waits for W-2's alarm.
  std::string set_up_fleet(bool healthy_too) {
    std::vector<PumpSpec> pumps = {
        {"W-2", reference_model, 4, 2.0, 1.0, 4, {"balance_piston_wear=1.5@run4"}}};
    if (healthy_too) pumps.push_back({"W-1", reference_model, 4, 2.0, 1.0, 3, {}});
    pumps_ = healthy_too ? "W-1,W-2" : "W-2";
    const auto runs = run_fleet(pumps, 2, 0.1);
    std::string faulty_run;
    for (const auto& o : runs)
      if (o.pump == "W-2" && o.run == 4) faulty_run = o.run_id;
    EXPECT_FALSE(faulty_run.empty());
    const auto deadline = std::chrono::steady_clock::now() + 10s;
    while (std::chrono::steady_clock::now() < deadline) {
      const auto r = get("/api/v1/alarms?pump_id=W-2");
      if (r && r->status == 200 && !json_of(r)["alarms"].empty()) break;
      std::this_thread::sleep_for(200ms);
    }
    return faulty_run;
  }

  // Runs the browser checks of the groups in `checks` (ui_test.mjs), its
  // screenshots in `shots` under build/web-screenshots; its exit code.
  int run_browser(const std::string& faulty_run, const std::string& checks, const std::string& shots = "") {
    env["AMBDIAG_URL"] = "http://127.0.0.1:" + std::to_string(port);
    env["AMBDIAG_VIEWER_TOKEN"] = tokens["viewer"];
    env["AMBDIAG_OPERATOR_TOKEN"] = tokens["operator"];
    env["AMBDIAG_ENGINEER_TOKEN"] = tokens["engineer"];
    env["AMBDIAG_PUMPS"] = pumps_;
    env["AMBDIAG_FAULTY_PUMP"] = "W-2";
    env["AMBDIAG_FAULTY_RUN"] = faulty_run;
    env["AMBDIAG_SCREENSHOTS"] = (fs::path(AMBDIAG_SCREENSHOTS) / shots).string();
    env["AMBDIAG_UI_CHECKS"] = checks;
    Process node({AMBDIAG_NODE, std::string(AMBDIAG_WEB_SOURCE) + "/tests/ui_test.mjs"}, env,
                 (dir / "browser.log").string());
    const int rc = node.wait(120s);
    std::printf("%s", node.log().c_str());
    if (rc != 0)
      ADD_FAILURE() << "browser checks failed (rc " << rc << "):\n"
                    << node.log() << "\n--- server ---\n"
                    << server->log();
    return rc;
  }
};

}  // namespace ambdiag::testing
