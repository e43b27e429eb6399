// Run recordings (`ambdiag.run/1`, ../shared/specs/run-recording.md): a
// folder with run.json (metadata) and samples.f32 (float32 little-endian,
// interleaved by channel).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace ambdiag {

struct PlantModel;

enum class ChannelRole { reference, force, displacement, acceleration, velocity, speed, other };
std::string to_string(ChannelRole r);

struct Channel {
  std::string name;
  ChannelRole role = ChannelRole::other;
  std::string role_text;  // as written (kept for roles the spec does not name)
  std::string unit;
  std::string input;                                // for role reference: the actuator it drives
  nlohmann::json extra = nlohmann::json::object();  // unknown keys, kept for round trips
};

enum class ExcitationType { multisine, stepsine, chirp, random, none };
std::string to_string(ExcitationType t);

// One segment. Which fields are meaningful depends on the excitation type:
//  multisine: start, periods, settle_periods, pattern
//  stepsine:  start, length, input, freq_hz, amplitude, settle_samples, meas_samples, periods
//  chirp/random: start, length
struct ExcitationSegment {
  int64_t start = 0;
  int64_t length = 0;
  int64_t periods = 0;
  int64_t settle_periods = 0;
  int pattern = 0;
  std::string input;
  double freq_hz = 0.0;
  double amplitude = 0.0;
  int64_t settle_samples = 0;
  int64_t meas_samples = 0;
  nlohmann::json extra = nlohmann::json::object();  // unknown keys, kept for round trips
};

struct Excitation {
  ExcitationType type = ExcitationType::none;
  int64_t period_samples = 0;  // multisine
  double f_min_hz = 0.0;
  double f_max_hz = 0.0;
  std::vector<ExcitationSegment> segments;
  nlohmann::json extra = nlohmann::json::object();  // unknown keys, kept for round trips
};

struct RunRecording {
  std::string pump_id;
  std::string run_id;
  std::string kind;        // identification | monitoring
  std::string started_at;  // ISO 8601
  double speed_rpm = 0.0;
  double sample_rate_hz = 0.0;
  std::vector<Channel> channels;
  std::optional<Excitation> excitation;
  nlohmann::json extra = nlohmann::json::object();  // unknown top-level keys

  std::vector<float> samples;  // interleaved: frame-major, channel-minor

  int64_t frame_count() const;
  int channel_index(const std::string& name) const;  // -1 if absent
  float at(int64_t frame, int channel) const {
    return samples[static_cast<size_t>(frame) * channels.size() + static_cast<size_t>(channel)];
  }
  // Throws InputError if sizes disagree (samples not whole frames, a
  // segment past the end, duplicate channel names, a reference without input),
  // a sample is NaN or infinite, or a value breaks a rule of the format
  // (docs/formats.md, "Run recording"); the message names the field.
  void validate() const;
  // All of validate() but the sample values (for readers that check each
  // value as they read it).
  void validate_structure() const;
  // Throws InputError if a channel names no sensor or actuator of the plant.
  void validate_against(const PlantModel& plant) const;
};

// Metadata only, no samples; checks every rule that does not need them.
RunRecording run_from_json(const nlohmann::json& doc);
nlohmann::json run_to_json(const RunRecording& run);
// Reads run.json and samples.f32 from a folder; throws InputError naming the
// file and what is wrong; never returns a half-read run.
RunRecording read_run(const std::string& dir);
// Writes both files, each via temporary file and rename.
void write_run(const std::string& dir, const RunRecording& run);

}  // namespace ambdiag
