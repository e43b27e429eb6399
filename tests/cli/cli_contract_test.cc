// The CLI contract of ../shared/specs/cli.md, checked on the real binary:
// exit codes, JSON on stdout, messages on stderr.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/io_util.h"
#include "ambdiag/core/run_recording.h"
#include "ambdiag/core/uff58.h"
#include "cli_run.h"
#include "test_support.h"

namespace ambdiag {
namespace {

using Result = testing::CliResult;

// Runs the ambdiag binary with shell-quoted arguments.
Result run(const std::string& args) { return testing::run_cli(args); }

std::string data(const std::string& rel) { return testing::data_file(rel).string(); }

TEST(Cli, ModelModesPrintsSortedJsonModesWithContractKeys) {
  const Result r = run("model modes " + data("reference_pump/plant.json") + " --json --fmax 1000");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_TRUE(j.contains("modes"));
  double last = -1;
  int forward = 0;
  for (const auto& m : j["modes"]) {
    ASSERT_TRUE(m.contains("f_hz") && m.contains("zeta") && m.contains("direction"));
    EXPECT_GE(m["f_hz"].get<double>(), last);
    last = m["f_hz"].get<double>();
    forward += m["whirl"] == "forward";
  }
  EXPECT_EQ(forward, 5);  // two rigid-body and three bending modes below 1 kHz
}

TEST(Cli, ModelModesHonoursSpeedOption) {
  const Result r = run("model modes " + data("reference_pump/plant.json") + " --speed 0 --json");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["speed_rpm"].get<double>(), 0.0);
}

TEST(Cli, UsageErrorsExitTwo) {
  EXPECT_EQ(run("").code, 2);
  EXPECT_EQ(run("frobnicate").code, 2);
  EXPECT_EQ(run("model modes").code, 2);
  EXPECT_EQ(run("model modes " + data("reference_pump/plant.json") + " --speed fast").code, 2);
  EXPECT_EQ(run("model modes " + data("reference_pump/plant.json") + " --bogus").code, 2);
  EXPECT_EQ(run("model frf " + data("reference_pump/plant.json")).code, 2);  // no -o
}

// serve's durability options (docs/streaming.md, "Durable acknowledgement"):
// a bad value is a usage error naming the option, before any file is touched.
TEST(Cli, ServeRefusesBadDurabilityOptionsNamingThem) {
  const std::string db = (testing::scratch_dir() / "never.db").string();
  for (const auto& [args, option] :
       {std::pair{"--durability sometimes", "--durability"}, std::pair{"--durable-within 0", "--durable-within"},
        std::pair{"--speak-protocol 2.0", "--speak-protocol"}, std::pair{"--speak-protocol 1.0", "--speak-protocol"}}) {
    const Result r = run("serve --db " + db + " --http-port 0 " + args);
    EXPECT_EQ(r.code, 2) << args;
    EXPECT_NE(r.err.find(option), std::string::npos) << r.err;
  }
  EXPECT_FALSE(std::filesystem::exists(db));
}

TEST(Cli, HelpExistsForEveryCommand) {
  for (const char* c : {"--help", "model --help", "model modes --help", "model frf --help", "convert --help"}) {
    const Result r = run(c);
    EXPECT_EQ(r.code, 0) << c;
    EXPECT_NE(r.out.find("usage"), std::string::npos) << c;
  }
}

TEST(Cli, BadInputExitsThreeNamingFileAndField) {
  const auto bad = testing::write_scratch("bad_plant.json",
                                          R"({"format":"ambdiag.plant/1","materials":{"s":{"E":2e11,"G":8e10,"rho":7800}},)"
                                          R"("shaft":[{"L":0.1,"od":0.05,"id":0.06,"material":"s"}]})");
  const Result r = run("model modes " + bad.string() + " --json");
  EXPECT_EQ(r.code, 3);
  EXPECT_NE(r.err.find("bad_plant.json"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("shaft[0].od: must be > id"), std::string::npos) << r.err;
  EXPECT_EQ(run("model modes /nonexistent.json").code, 3);
}

TEST(Cli, ModelFrfWritesAReadableFrfFileAtTheRequestedGrid) {
  const auto out = testing::scratch_dir() / "model.csv";
  const Result r = run("model frf " + data("reference_pump/plant.json") + " -o " + out.string() +
                       " --fmin 10 --fmax 100 --df 5");
  ASSERT_EQ(r.code, 0) << r.err;
  const FrfData f = read_frf_csv(out.string());
  EXPECT_EQ(f.freq_hz.size(), 19u);
  EXPECT_EQ(f.entries.size(), 25u);
}

// Recordings after the first judge the explanation at their speeds
// (explain.h): the model's own FRFs at two speeds leave nothing to explain
// at either; the same speed twice is refused as bad input naming speed_rpm.
TEST(CliExplain, RecordingsAtOtherSpeedsAreJudgedAndOneAtTheSameSpeedRefused) {
  const auto dir = testing::scratch_dir();
  const std::string plant = data("reference_pump/plant.json");
  for (const char* rpm : {"2950", "2200"}) {
    const Result m = run("model frf " + plant + " -o " + (dir / (std::string(rpm) + ".csv")).string() + " --fmin 4 --fmax 400 --df 4 --speed " + rpm);
    ASSERT_EQ(m.code, 0) << m.err;
  }
  const std::string a = (dir / "2950.csv").string(), b = (dir / "2200.csv").string();
  const Result r = run("explain --model " + plant + " --measured " + a + " " + b + " --json");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["explanations"].empty()) << j["explanations"].dump();
  ASSERT_EQ(j["other_speeds"].size(), 1u) << r.out.substr(0, 400);
  EXPECT_EQ(j["other_speeds"][0]["speed_rpm"], 2200.0);
  EXPECT_TRUE(j["other_speeds"][0]["unexplained"].empty());
  const Result same = run("explain --model " + plant + " --measured " + a + " " + a + " --json");
  EXPECT_EQ(same.code, 3) << same.err;
  EXPECT_NE(same.err.find("speed_rpm"), std::string::npos) << same.err;
}

TEST(Cli, ConvertRoundTripsAnFrfThroughUff58) {
  const auto dir = testing::scratch_dir();
  const std::string src = data("ident_7mode/frf.csv");
  for (const std::string flag : {"", " --binary"}) {
    ASSERT_EQ(run("convert " + src + " " + (dir / "x.uff").string() + flag).code, 0);
    ASSERT_EQ(run("convert " + (dir / "x.uff").string() + " " + (dir / "back.csv").string()).code, 0);
    const FrfData a = read_frf_csv(src), b = read_frf_csv((dir / "back.csv").string());
    ASSERT_EQ(a.entries.size(), b.entries.size());
    EXPECT_EQ(a.freq_hz, b.freq_hz);
    EXPECT_EQ(a.entries[0].h, b.entries[0].h) << "UFF58 round trip must be lossless" << flag;
  }
}

TEST(Cli, ConvertReadsForeignTimeDataToCsvAndRefusesTruncatedFiles) {
  const auto dir = testing::scratch_dir();
  const Result ok = run("convert " + data("external/uff/binary8byte.uff") + " " + (dir / "t.csv").string());
  ASSERT_EQ(ok.code, 0) << ok.err;
  std::ifstream in(dir / "t.csv");
  int lines = 0;
  for (std::string l; std::getline(in, l);) ++lines;
  EXPECT_EQ(lines, 2 + 250);  // comment, header, 250 samples
  std::ifstream src(data("external/uff/Sample_UFF58b_bin.uff"), std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(src)), std::istreambuf_iterator<char>());
  const auto cut = testing::write_scratch("cut.uff", bytes.substr(0, bytes.size() / 3));
  const Result bad = run("convert " + cut.string() + " " + (dir / "c.csv").string());
  EXPECT_EQ(bad.code, 3);
  EXPECT_NE(bad.err.find("cut.uff"), std::string::npos) << bad.err;
}

}  // namespace
}  // namespace ambdiag

namespace ambdiag {
namespace {

TEST(CliFit, FitsTheSevenModeFileWithContractKeys) {
  const Result r = run("fit " + data("ident_7mode/frf.csv") + " --json");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["order"].get<int>(), 14);  // 7 pole pairs, as FREQID's order 14
  ASSERT_EQ(j["modes"].size(), 7u);
  double last = 0;
  for (const auto& m : j["modes"]) {
    for (const char* k : {"f_hz", "zeta", "f_sd_hz", "zeta_sd", "direction"}) EXPECT_TRUE(m.contains(k)) << k;
    EXPECT_GT(m["f_hz"].get<double>(), last);
    last = m["f_hz"].get<double>();
  }
}

TEST(CliFit, LabelsReferencePumpModesAgainstTheModelLikeTableThree) {
  const auto svg = testing::scratch_dir() / "stab.svg";
  const Result r = run("fit " + data("reference_pump/frf_ref_2.csv") + " --model " + data("reference_pump/plant.json") +
                       " --json --svg " + svg.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_TRUE(j.contains("unmatched_model_modes") && j.contains("unmatched_identified_modes"));
  int labelled = 0;
  for (const auto& m : j["modes"]) {
    if (!m.contains("label")) continue;
    ++labelled;
    EXPECT_NEAR(m["f_hz"].get<double>(), m["model_f_hz"].get<double>(), 0.01 * m["model_f_hz"].get<double>()) << m["label"];
  }
  EXPECT_GE(labelled, 10);  // five whirl pairs, the housing and the axial mode: 12 in the band
  EXPECT_TRUE(std::filesystem::exists(svg));
}

TEST(CliFit, RefusesAMalformedFrfFileWithExitThree) {
  const auto bad = testing::write_scratch("bad.csv", "# ambdiag.frf/1\nfreq_hz,H_a_b_re,H_a_b_im\n1,0.1,x\n");
  const Result r = run("fit " + bad.string() + " --json");
  EXPECT_EQ(r.code, 3);
  EXPECT_NE(r.err.find("bad.csv"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace ambdiag

namespace ambdiag {
namespace {

TEST(CliFrf, EstimatesAMultisineRunIntoAReadableFrfFile) {
  const auto out = testing::scratch_dir() / "ref1.csv";
  const Result r = run("frf " + data("reference_pump/run_ref_1") + " -o " + out.string() + " --json --plant " +
                       data("reference_pump/plant.json"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["method"], "multisine");
  EXPECT_EQ(j["lines"], 1000);
  EXPECT_EQ(j["entries"], 25);
  EXPECT_TRUE(j["warnings"].empty());
  const FrfData f = read_frf_csv(out.string());
  EXPECT_EQ(f.freq_hz.size(), 1000u);
  ASSERT_EQ(f.entries.size(), 25u);
  EXPECT_EQ(f.entries[0].sigma.size(), 1000u);
  EXPECT_EQ(f.entries[0].coh.size(), 1000u);
  EXPECT_EQ(f.meta("method"), "multisine");
  EXPECT_EQ(f.meta("pump_id"), "P-101");
  EXPECT_EQ(f.speed_rpm, 2950.0);
}

// The Bode plot measured vs model: an SVG document naming the run, with a
// measured and a model series per entry shown (four strongest).
TEST(CliFrf, SvgDrawsMeasuredAgainstTheModel) {
  const auto dir = testing::scratch_dir();
  const auto svg = dir / "bode.svg";
  const Result r = run("frf " + data("reference_pump/run_ref_1") + " -o " + (dir / "f.csv").string() + " --plant " +
                       data("reference_pump/plant.json") + " --svg " + svg.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string text = read_file_bytes(svg.string());
  EXPECT_NE(text.find("<svg"), std::string::npos);
  EXPECT_NE(text.find("run_ref_1: measured (solid) vs model (dashed), NRMSE 0.0"), std::string::npos);
  size_t measured = 0, model = 0;
  for (size_t at = text.find(" measured<"); at != std::string::npos; at = text.find(" measured<", at + 1)) ++measured;
  for (size_t at = text.find(" model<"); at != std::string::npos; at = text.find(" model<", at + 1)) ++model;
  EXPECT_EQ(measured, 4u);
  EXPECT_EQ(model, 4u);
}

TEST(CliFrf, BrokenRunExitsThreeNamingTheFolderAndTheChannel) {
  RunRecording bad = read_run(data("reference_pump/run_ref_1"));
  const int c = bad.channel_index("rZ");
  for (int64_t t = 0; t < bad.frame_count(); ++t) bad.samples[static_cast<size_t>(t) * bad.channels.size() + c] = 0;
  const auto scratch = testing::scratch_dir(), dir = scratch / "zero_reference_run";
  write_run(dir.string(), bad);
  const Result r = run("frf " + dir.string() + " -o " + (scratch / "x.csv").string());
  EXPECT_EQ(r.code, 3);
  EXPECT_NE(r.err.find("zero_reference_run"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("reference channel rZ"), std::string::npos) << r.err;
}

TEST(CliFrf, WarningsGoToStderrAndToTheFileMetadata) {
  const auto out = testing::scratch_dir() / "amrotor.csv";
  // Welch windows taper the sweep's ends: lines there are dropped, with a warning.
  const Result r = run("frf " + data("external/amrotor_mlps_sweep") + " -o " + out.string() + " --method welch");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("warning"), std::string::npos) << r.err;
  const FrfData f = read_frf_csv(out.string());
  EXPECT_TRUE(f.meta("warning_1").has_value());
  EXPECT_EQ(f.quantity, FrfQuantity::accelerance);
  EXPECT_EQ(f.unit, "(m/s^2)/V");
}

TEST(CliFrf, UsageErrorsExitTwo) {
  EXPECT_EQ(run("frf " + data("reference_pump/run_ref_1")).code, 2);  // no -o
  EXPECT_EQ(run("frf " + data("reference_pump/run_ref_1") + " -o x.csv --method h2").code, 2);
  EXPECT_EQ(run("frf " + data("reference_pump/run_ref_1") + " -o x.csv --nfft 1001").code, 2);
  EXPECT_EQ(run("frf " + data("reference_pump/run_ref_1") + " -o x.csv --svg b.svg").code, 2);  // --svg needs --plant
  const Result h = run("frf --help");
  EXPECT_EQ(h.code, 0);
  EXPECT_NE(h.out.find("usage: ambdiag frf"), std::string::npos);
}

}  // namespace
}  // namespace ambdiag

namespace ambdiag {
namespace {

TEST(CliCampbell, ReportsTracksCriticalSpeedsAndAnSvg) {
  const auto svg = testing::scratch_dir() / "campbell.svg";
  const Result r = run("model campbell " + data("reference_pump/plant.json") + " --steps 7 --json --svg " + svg.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_GE(j["tracks"].size(), 8u);
  EXPECT_TRUE(j.contains("critical_speeds"));
  EXPECT_TRUE(std::filesystem::exists(svg));
  EXPECT_EQ(run("model campbell " + data("reference_pump/plant.json") + " --steps 1").code, 2);
}

}  // namespace
}  // namespace ambdiag
