#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "ambdiag/core/error.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/run_recording.h"
#include "test_support.h"

namespace ambdiag {
namespace {

using ambdiag::testing::data_file;
using ambdiag::testing::scratch_dir;
using nlohmann::json;

bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

// 4 channels, fs 1000 Hz, two multisine segments of 3 periods of 10 samples: 60 frames.
json small_multisine() {
  return json::parse(R"({
    "format": "ambdiag.run/1", "pump_id": "P-1", "run_id": "P-1/t", "kind": "identification",
    "started_at": "2026-01-01T00:00:00Z", "speed_rpm": 1500, "sample_rate_hz": 1000,
    "channels": [
      {"name": "rAx", "role": "reference", "unit": "N", "input": "fAx"},
      {"name": "fAx", "role": "force", "unit": "N"},
      {"name": "xAx", "role": "displacement", "unit": "m"},
      {"name": "speed", "role": "speed", "unit": "rpm"}],
    "excitation": {"type": "multisine", "period_samples": 10, "f_min_hz": 100, "f_max_hz": 400,
      "segments": [{"start": 0, "periods": 3, "settle_periods": 1, "pattern": 0},
                   {"start": 30, "periods": 3, "settle_periods": 1, "pattern": 1}]}})");
}

// Same channels, one stepsine segment: 20 settling + 100 measuring samples
// holding 5 periods of 50 Hz at 1000 Hz.
json small_stepsine() {
  json doc = small_multisine();
  doc["excitation"] =
      json::parse(R"({"type": "stepsine", "f_min_hz": 50, "f_max_hz": 60, "n_steps_per_input": 1,
      "segments": [{"start": 0, "length": 120, "input": "fAx", "freq_hz": 50, "amplitude": 2.5,
                    "settle_samples": 20, "meas_samples": 100, "periods": 5}]})");
  return doc;
}

std::vector<float> ramp(size_t n) {
  std::vector<float> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = static_cast<float>(std::sin(0.1 * static_cast<double>(i)) * 1e-3);
  return v;
}

std::string float_bytes(const std::vector<float>& v) {
  std::string b(v.size() * 4, '\0');
  std::memcpy(b.data(), v.data(), b.size());
  return b;
}

// Writes a run folder from raw run.json text and raw samples bytes.
std::filesystem::path make_run(const std::string& name, const std::string& run_json,
                               const std::string& samples) {
  const auto dir = scratch_dir() / name;
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "run.json", std::ios::binary) << run_json;
  std::ofstream(dir / "samples.f32", std::ios::binary) << samples;
  return dir;
}

std::string read_error(const std::filesystem::path& dir) {
  try {
    read_run(dir.string());
  } catch (const InputError& e) {
    return e.what();
  }
  return "<accepted>";
}

std::string error_of(const json& doc) {
  try {
    run_from_json(doc);
  } catch (const InputError& e) {
    return e.what();
  }
  return "<accepted>";
}

PlantModel pump_points() {
  PlantModel plant;
  plant.name = "pump";
  for (const char* s : {"xAx", "xAy", "xBx", "xBy", "xZ"})
    plant.sensors.push_back(MeasurementPoint{s, "A", 1, 'x'});
  for (const char* a : {"fAx", "fAy", "fBx", "fBy", "fZ"}) {
    plant.actuators.push_back(MeasurementPoint{a, "A", 1, 'x'});
  }
  return plant;
}

// --- the shared recordings --------------------------------------------------

struct SharedRun {
  const char* dir;
  size_t channels;
  int64_t frames;
  ExcitationType type;
  size_t segments;
  bool pump;  // channels named after the reference pump's plant model
};

class SharedRunFolder : public ::testing::TestWithParam<SharedRun> {};

TEST_P(SharedRunFolder, ParsesAndValidates) {
  const SharedRun& p = GetParam();
  const RunRecording run = read_run(data_file(p.dir).string());
  EXPECT_EQ(run.channels.size(), p.channels);
  EXPECT_EQ(run.frame_count(), p.frames);
  ASSERT_TRUE(run.excitation.has_value());
  EXPECT_EQ(run.excitation->type, p.type);
  EXPECT_EQ(run.excitation->segments.size(), p.segments);
  EXPECT_NO_THROW(run.validate());
  if (p.pump) {
    const PlantModel plant = read_plant_file(data_file("reference_pump/plant.json").string());
    EXPECT_NO_THROW(run.validate_against(plant));
  }
}

TEST_P(SharedRunFolder, RunJsonRoundTripsLosslessly) {
  const auto path = data_file(GetParam().dir) / "run.json";
  std::ifstream in(path);
  const json doc = json::parse(in);
  EXPECT_EQ(run_to_json(run_from_json(doc)), doc);
}

const SharedRun kSharedRuns[] = {
    {"reference_pump/run_ref_1", 16, 102400, ExcitationType::multisine, 5, true},
    {"reference_pump/run_stepsine", 16, 177530, ExcitationType::stepsine, 300, true},
    {"fault_dry_run/run", 16, 102400, ExcitationType::multisine, 5, true},
    {"fault_crack/run", 16, 102400, ExcitationType::multisine, 5, true},
    {"external/amrotor_mlps_sweep", 9, 32768, ExcitationType::chirp, 1, false},
};
INSTANTIATE_TEST_SUITE_P(RunRecording, SharedRunFolder, ::testing::ValuesIn(kSharedRuns));

TEST(RunRecording, ReadsStepsineSegmentsAndKeepsExcitationExtras) {
  const RunRecording run = read_run(data_file("reference_pump/run_stepsine").string());
  const ExcitationSegment& s = run.excitation->segments.at(1);
  EXPECT_EQ(s.start, 1802);
  EXPECT_EQ(s.length, 1662);
  EXPECT_EQ(s.input, "fAx");
  EXPECT_EQ(s.settle_samples + s.meas_samples, s.length);
  EXPECT_EQ(run.excitation->extra.at("n_steps_per_input"), 60);
  EXPECT_EQ(run.channel_index("xBy"), 13);
  EXPECT_EQ(run.channel_index("nope"), -1);
  EXPECT_EQ(run.channels[0].role, ChannelRole::reference);
  EXPECT_EQ(run.channels[0].input, "fAx");
}

TEST(RunRecording, ReadsTheExternalRigWithFreeChannelNames) {
  const RunRecording run = read_run(data_file("external/amrotor_mlps_sweep").string());
  EXPECT_EQ(run.channels[0].unit, "V");
  EXPECT_EQ(run.channels[1].role, ChannelRole::acceleration);
  EXPECT_EQ(run.excitation->f_min_hz, 0.0);
  // Accelerations are exempt from the plant check; only the reference's input must be an actuator.
  PlantModel rig;
  rig.actuators.push_back(MeasurementPoint{"u", "A", 1, 'x'});
  EXPECT_NO_THROW(run.validate_against(rig));
}

// --- writing ----------------------------------------------------------------

TEST(RunRecording, WriteThenReadIsBitIdentical) {
  RunRecording run = read_run(data_file("reference_pump/run_stepsine").string());
  run.samples[5] = std::numeric_limits<float>::denorm_min();
  run.samples[6] = -0.0f;
  const auto dir = scratch_dir() / "out";
  write_run(dir.string(), run);
  const RunRecording back = read_run(dir.string());
  EXPECT_EQ(run_to_json(back), run_to_json(run));
  ASSERT_EQ(back.samples.size(), run.samples.size());
  EXPECT_EQ(std::memcmp(back.samples.data(), run.samples.data(), run.samples.size() * 4), 0);
}

TEST(RunRecording, UnknownKeysSurviveARoundTripAtEveryLevel) {
  json doc = small_multisine();
  doc["operator"] = {{"name", "A. N. Other"}};
  doc["channels"][2]["gain"] = 1.5;
  doc["channels"][0]["calibrated"] = true;
  doc["excitation"]["crest_factor"] = 1.4;
  doc["excitation"]["segments"][1]["note"] = "second";
  const RunRecording run = run_from_json(doc);
  EXPECT_EQ(run.extra.at("operator").at("name"), "A. N. Other");
  EXPECT_EQ(run.channels[2].extra.at("gain"), 1.5);
  EXPECT_EQ(run_to_json(run), doc);
}

TEST(RunRecording, RefusesUnknownValuesNestedWithoutBound) {
  const std::string deep = std::string(20000, '[') + std::string(20000, ']');
  json doc = small_multisine();
  doc["channels"][1]["blob"] = json::parse(deep);
  EXPECT_PRED2(contains, error_of(doc), "channels[1].blob: nested deeper than 64 levels");
  doc = small_multisine();
  doc["blob"] = json::parse("[[[1]]]");
  EXPECT_EQ(error_of(doc), "<accepted>");
}

TEST(RunRecording, MonitoringRunsNeedNoExcitation) {
  json doc = small_multisine();
  doc["kind"] = "monitoring";
  doc.erase("excitation");
  const RunRecording run = run_from_json(doc);
  EXPECT_FALSE(run.excitation.has_value());
  EXPECT_EQ(run_to_json(run), doc);
  doc["kind"] = "identification";
  EXPECT_PRED2(contains, error_of(doc), "excitation: missing (required for kind identification)");
}

TEST(RunRecording, WriteRefusesAnInvalidRun) {
  RunRecording run = run_from_json(small_multisine());
  run.samples = ramp(4 * 59);  // one frame short of the last segment
  EXPECT_THROW(write_run((scratch_dir() / "out").string(), run), InputError);
  EXPECT_FALSE(std::filesystem::exists(scratch_dir() / "out" / "run.json"));
}

TEST(RunRecording, FrameAccessIsFrameMajor) {
  RunRecording run = run_from_json(small_multisine());
  run.samples = ramp(4 * 60);
  EXPECT_EQ(run.frame_count(), 60);
  EXPECT_EQ(run.at(7, 2), run.samples[7 * 4 + 2]);
}

TEST(RunRecording, EnumNames) {
  EXPECT_EQ(to_string(ChannelRole::displacement), "displacement");
  EXPECT_EQ(to_string(ChannelRole::velocity), "velocity");
  EXPECT_EQ(to_string(ExcitationType::stepsine), "stepsine");
  EXPECT_EQ(to_string(ExcitationType::random), "random");
}

// --- refused recordings -----------------------------------------------------

TEST(RunRecording, ReadsASmallMultisineAndStepsineRun) {
  EXPECT_EQ(read_error(make_run("ms", small_multisine().dump(), float_bytes(ramp(4 * 60)))), "<accepted>");
  EXPECT_EQ(read_error(make_run("ss", small_stepsine().dump(), float_bytes(ramp(4 * 120)))), "<accepted>");
}

TEST(RunRecording, RefusesTruncatedSamplesNamingTheFile) {
  std::string bytes = float_bytes(ramp(4 * 60));
  bytes.resize(bytes.size() - 3);
  const auto dir = make_run("run", small_multisine().dump(), bytes);
  EXPECT_PRED2(
      contains, read_error(dir),
      (dir / "samples.f32").string() + ": 957 bytes is not a whole number of frames (4 channels x 4 bytes)");
}

TEST(RunRecording, RefusesASegmentPastTheEndNamingTheSegment) {
  const auto dir = make_run("run", small_multisine().dump(), float_bytes(ramp(4 * 50)));
  EXPECT_PRED2(contains, read_error(dir),
               "excitation.segments[1]: ends at sample 60, past the end of the recording (50 frames)");
}

TEST(RunRecording, RefusesEmptySamples) {
  EXPECT_PRED2(contains, read_error(make_run("run", small_multisine().dump(), "")), "samples: no frames");
}

TEST(RunRecording, RefusesANaNSampleNamingFrameAndChannel) {
  std::vector<float> v = ramp(4 * 60);
  v[3 * 4 + 2] = std::numeric_limits<float>::quiet_NaN();
  const auto dir = make_run("run", small_multisine().dump(), float_bytes(v));
  EXPECT_PRED2(contains, read_error(dir), "samples.f32: frame 3, channel xAx: NaN or infinite sample");
}

// The reader checks the file piece by piece (64 Ki values) and the check
// runs over groups of 16: a bad value past the first piece, and one in a
// group's tail, are found and named, the first in file order.
TEST(RunRecording, FindsTheFirstNonFiniteSampleAnywhereInALongFile) {
  const size_t frames = 40001;  // 160004 values: three pieces, a tail of 4 after the last group of 16
  std::vector<float> v = ramp(4 * frames);
  v[4 * 30000 + 1] = std::numeric_limits<float>::infinity();
  v[4 * 40000 + 3] = std::numeric_limits<float>::quiet_NaN();
  const auto dir = make_run("long", small_multisine().dump(), float_bytes(v));
  EXPECT_PRED2(contains, read_error(dir), "samples.f32: frame 30000, channel fAx: NaN or infinite sample");

  v[4 * 30000 + 1] = 0.0f;  // only the last value of the file is left
  const auto dir2 = make_run("long2", small_multisine().dump(), float_bytes(v));
  const std::string e = read_error(dir2);
  EXPECT_NE(e.find("samples.f32: frame 40000, channel speed: NaN"), std::string::npos) << e;

  RunRecording run = read_run(make_run("long3", small_multisine().dump(), float_bytes(ramp(4 * frames))));
  run.validate();  // all finite
  run.samples.back() = -std::numeric_limits<float>::infinity();
  try {
    run.validate();
    ADD_FAILURE() << "validate() accepted an infinite sample";
  } catch (const InputError& err) {
    EXPECT_NE(std::string(err.what()).find("frame 40000"), std::string::npos) << err.what();
  }
}

TEST(RunRecording, RefusesAFolderWithoutRunJsonOrSamplesNamingTheFile) {
  const auto dir = make_run("run", small_multisine().dump(), float_bytes(ramp(4 * 60)));
  std::filesystem::remove(dir / "samples.f32");
  EXPECT_PRED2(contains, read_error(dir), (dir / "samples.f32").string() + ": missing");
  std::filesystem::remove(dir / "run.json");
  EXPECT_PRED2(contains, read_error(dir), (dir / "run.json").string() + ": missing");
  EXPECT_PRED2(contains, read_error(dir / "absent"), "not a run folder");
}

TEST(RunRecording, RefusesInvalidJsonNamingTheFile) {
  const auto dir = make_run("run", "{\"format\": ", float_bytes(ramp(4)));
  EXPECT_PRED2(contains, read_error(dir), (dir / "run.json").string() + ": invalid JSON");
}

TEST(RunRecording, ErrorsInRunJsonNameTheFileAndTheField) {
  json doc = small_multisine();
  doc["sample_rate_hz"] = "fast";
  const auto dir = make_run("run", doc.dump(), float_bytes(ramp(4 * 60)));
  EXPECT_PRED2(contains, read_error(dir), (dir / "run.json").string() + ": sample_rate_hz: must be a number");
}

TEST(RunRecording, RefusesWrongTypes) {
  json doc = small_multisine();
  doc["channels"] = json::object();
  EXPECT_PRED2(contains, error_of(doc), "channels: must be an array");
  doc = small_multisine();
  doc["excitation"]["segments"][1]["start"] = "30";
  EXPECT_PRED2(contains, error_of(doc), "excitation.segments[1].start: must be an integer");
  doc = small_multisine();
  doc["excitation"]["segments"][0]["periods"] = 2.5;
  EXPECT_PRED2(contains, error_of(doc), "excitation.segments[0].periods: must be an integer");
  doc = small_multisine();
  doc["channels"][1]["name"] = 7;
  EXPECT_PRED2(contains, error_of(doc), "channels[1].name: must be a string");
  EXPECT_PRED2(contains, error_of(json::array()), "must be a JSON object");
}

TEST(RunRecording, RefusesMissingFields) {
  for (const char* key :
       {"format", "pump_id", "run_id", "kind", "started_at", "speed_rpm", "sample_rate_hz", "channels"}) {
    json doc = small_multisine();
    doc.erase(key);
    EXPECT_PRED2(contains, error_of(doc), std::string(key) + ": missing");
  }
  json doc = small_multisine();
  doc["excitation"].erase("period_samples");
  EXPECT_PRED2(contains, error_of(doc), "excitation.period_samples: missing");
  doc = small_stepsine();
  doc["excitation"]["segments"][0].erase("meas_samples");
  EXPECT_PRED2(contains, error_of(doc), "excitation.segments[0].meas_samples: missing");
  doc = small_multisine();
  doc["channels"][2].erase("unit");
  EXPECT_PRED2(contains, error_of(doc), "channels[2].unit: missing");
}

TEST(RunRecording, RefusesAWrongFormatOrKind) {
  json doc = small_multisine();
  doc["format"] = "ambdiag.run/2";
  EXPECT_PRED2(contains, error_of(doc), "format: must be \"ambdiag.run/1\"");
  doc = small_multisine();
  doc["kind"] = "testing";
  EXPECT_PRED2(contains, error_of(doc), "kind: must be identification or monitoring");
}

TEST(RunRecording, RefusesAReferenceWithoutInput) {
  json doc = small_multisine();
  doc["channels"][0].erase("input");
  EXPECT_PRED2(contains, error_of(doc), "channels[0]: a reference channel needs 'input'");
}

TEST(RunRecording, RefusesDuplicateChannelNames) {
  json doc = small_multisine();
  doc["channels"][3]["name"] = "fAx";
  EXPECT_PRED2(contains, error_of(doc), "channels[3].name: duplicate channel name 'fAx'");
}

TEST(RunRecording, RefusesAHugeOrNonPositiveSampleRate) {
  json doc = small_multisine();
  doc["sample_rate_hz"] = 1e300;
  EXPECT_PRED2(contains, error_of(doc), "sample_rate_hz: must be <= 1e8");
  doc["sample_rate_hz"] = 0;
  EXPECT_PRED2(contains, error_of(doc), "sample_rate_hz: must be > 0");
}

TEST(RunRecording, RefusesANegativeStart) {
  json doc = small_multisine();
  doc["excitation"]["segments"][1]["start"] = -1;
  EXPECT_PRED2(contains, error_of(doc), "excitation.segments[1].start: must be >= 0");
}

TEST(RunRecording, RefusesSegmentsWhoseEndOverflows) {
  json doc = small_multisine();
  doc["excitation"]["segments"][1]["periods"] = int64_t{1} << 62;
  EXPECT_PRED2(contains, error_of(doc), "excitation.segments[1]: periods x period_samples overflows");
}

TEST(RunRecording, RefusesMultisineSegmentsWithoutUsablePeriods) {
  json doc = small_multisine();
  doc["excitation"]["segments"][0]["settle_periods"] = 3;
  EXPECT_PRED2(contains, error_of(doc), "excitation.segments[0].settle_periods: must be < periods");
}

TEST(RunRecording, RefusesAStepsineWhoseSettleAndMeasureDoNotMakeItsLength) {
  json doc = small_stepsine();
  doc["excitation"]["segments"][0]["length"] = 121;
  EXPECT_PRED2(contains, error_of(doc),
               "excitation.segments[0]: settle_samples + meas_samples (20 + 100) must equal length (121)");
}

TEST(RunRecording, RefusesAStepsineWhoseMeasurementIsNotWholePeriods) {
  json doc = small_stepsine();
  doc["excitation"]["segments"][0]["freq_hz"] = 51;
  EXPECT_PRED2(contains, error_of(doc), "excitation.segments[0]: meas_samples hold 5.1");
}

TEST(RunRecording, RefusesAStepsineInputThatNoReferenceDrives) {
  json doc = small_stepsine();
  doc["excitation"]["segments"][0]["input"] = "fBy";
  EXPECT_PRED2(contains, error_of(doc),
               "excitation.segments[0].input: 'fBy' is the input of no reference channel");
}

TEST(RunRecording, RefusesAnUnknownExcitationTypeAndBadBand) {
  json doc = small_multisine();
  doc["excitation"]["type"] = "impulse";
  EXPECT_PRED2(contains, error_of(doc), "excitation.type: must be multisine, stepsine, chirp or random");
  doc = small_multisine();
  doc["excitation"]["f_max_hz"] = 600;
  EXPECT_PRED2(contains, error_of(doc), "excitation.f_max_hz: must be <= sample_rate_hz / 2");
  doc = small_multisine();
  doc["excitation"]["segments"] = json::array();
  EXPECT_PRED2(contains, error_of(doc), "excitation.segments: must not be empty");
}

TEST(RunRecording, ValidateAgainstRefusesChannelsThePlantLacks) {
  RunRecording run = run_from_json(small_multisine());
  run.samples = ramp(4 * 60);
  const PlantModel plant = pump_points();
  EXPECT_NO_THROW(run.validate_against(plant));
  auto error_against = [&](const RunRecording& r) {
    try {
      r.validate_against(plant);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("<accepted>");
  };
  RunRecording bad = run;
  bad.channels[0].input = "fQ";
  EXPECT_PRED2(contains, error_against(bad), "channels[0] (rAx): input 'fQ' is not an actuator of the plant");
  bad = run;
  bad.channels[1].name = "fQ";
  EXPECT_PRED2(contains, error_against(bad),
               "channels[1] (fQ): a force channel must be named after an actuator");
  bad = run;
  bad.channels[2].name = "xQ";
  EXPECT_PRED2(contains, error_against(bad),
               "channels[2] (xQ): a displacement channel must be named after a sensor");
  bad = run;
  bad.channels[2].role = ChannelRole::velocity;
  EXPECT_NO_THROW(bad.validate_against(plant));
}

}  // namespace
}  // namespace ambdiag
