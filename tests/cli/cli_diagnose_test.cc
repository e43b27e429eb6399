// `ambdiag diagnose` on the real binary: the JSON keys of
// ../shared/specs/cli.md, the SVG, exit codes 2 and 3.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "cli_run.h"
#include "test_support.h"

namespace ambdiag {
namespace {

using Result = testing::CliResult;
Result run(const std::string& args) { return testing::run_cli(args); }

std::string data(const std::string& rel) { return testing::data_file(rel).string(); }

std::string refs() {
  std::string s = "--reference";
  for (int i = 1; i <= 5; ++i) s += " " + data("reference_pump/frf_ref_" + std::to_string(i) + ".csv");
  return s;
}

TEST(CliDiagnose, DryRunGivesTheContractKeysAndAnSvg) {
  const std::string svg = (testing::scratch_dir() / "dry.svg").string();
  const Result r = run("diagnose --model " + data("reference_pump/plant.json") + " " + refs() + " --measured " +
                       data("fault_dry_run/frf.csv") + " --json --svg " + svg);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  for (const char* k : {"detected", "statistic", "threshold", "symptoms", "faults", "fit"}) EXPECT_TRUE(j.contains(k)) << k;
  EXPECT_TRUE(j["detected"].get<bool>());
  EXPECT_GT(j["statistic"].get<double>(), j["threshold"].get<double>());
  ASSERT_FALSE(j["faults"].empty());
  const auto& first = j["faults"][0];
  EXPECT_EQ(first["fault"], "dry_run");
  EXPECT_TRUE(first.contains("score") && first.contains("parameters"));
  EXPECT_LT(j["fit"]["nrmse_after"].get<double>(), j["fit"]["nrmse_before"].get<double>());
  double last = 2.0;
  for (const auto& f : j["faults"]) {
    EXPECT_LE(f["score"].get<double>(), last);  // best first
    last = f["score"].get<double>();
  }
  std::ifstream in(svg);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("<svg"), std::string::npos);
}

TEST(CliDiagnose, HealthyRunIsNotDetected) {
  std::string some = "--reference";
  for (int i = 2; i <= 5; ++i) some += " " + data("reference_pump/frf_ref_" + std::to_string(i) + ".csv");
  const Result r = run("diagnose --model " + data("reference_pump/plant.json") + " " + some + " --measured " +
                       data("reference_pump/frf_ref_1.csv") + " --json");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_FALSE(j["detected"].get<bool>());
  EXPECT_TRUE(j["faults"].empty());
}

// References at another speed than the measurement are accepted (the model
// is evaluated at each run's speed); --same-speed keeps the older test,
// which refuses them.
TEST(CliDiagnose, MeasurementAtAnotherSpeedIsAcceptedUnlessSameSpeedIsAsked) {
  std::ifstream in(data("reference_pump/frf_ref_1.csv"));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto at = text.find("# speed_rpm: 2950");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, std::string("# speed_rpm: 2950").size(), "# speed_rpm: 3038.5");
  const std::string faster = testing::write_scratch("faster.csv", text).string();
  std::string some = "--reference";
  for (int i = 2; i <= 4; ++i) some += " " + data("reference_pump/frf_ref_" + std::to_string(i) + ".csv");
  const std::string saved = (testing::scratch_dir() / "operating_reference.json").string();
  const Result r = run("diagnose --model " + data("reference_pump/plant.json") + " " + some + " --measured " + faster +
                       " --json --save-reference " + saved);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_DOUBLE_EQ(j["operating"]["speed_rpm"].get<double>(), 3038.5);
  EXPECT_EQ(j["reference"]["speeds_rpm"].size(), 3u);
  EXPECT_EQ(j["detected"].get<bool>(), j["statistic"].get<double>() > j["threshold"].get<double>());
  std::ifstream saved_in(saved);
  EXPECT_EQ(nlohmann::json::parse(saved_in)["format"], "ambdiag.operating_reference/1");
  EXPECT_EQ(run("diagnose --model " + data("reference_pump/plant.json") + " " + some + " --measured " + faster + " --json --same-speed").code,
            3);
}

TEST(CliDiagnose, UsageAndBadInput) {
  EXPECT_EQ(run("diagnose --model " + data("reference_pump/plant.json")).code, 2);
  EXPECT_EQ(run("diagnose --help").code, 0);
  const std::string bad = testing::write_scratch("bad.csv", "# ambdiag.frf/1\nfreq_hz,H_xAx_fAx_re\n1.0,abc\n").string();
  const Result r = run("diagnose --model " + data("reference_pump/plant.json") + " " + refs() + " --measured " + bad + " --json");
  EXPECT_EQ(r.code, 3);
  EXPECT_NE(r.err.find("bad.csv"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace ambdiag
