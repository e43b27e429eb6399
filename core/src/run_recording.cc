// The run recording (`ambdiag.run/1`): run.json metadata and samples.f32.
//
// run_from_json checks types (JsonField names the field in each error);
// check_metadata checks values and their relations, so that recordings
// built in code and recordings read from disk obey the same rules;
// RunRecording::validate adds the checks that need the samples.
#include "ambdiag/core/run_recording.h"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "ambdiag/core/error.h"
#include "ambdiag/core/io_util.h"
#include "ambdiag/core/plant_model.h"
#include "json_fields.h"

namespace ambdiag {
namespace {

using detail::JsonField;
using nlohmann::json;

constexpr const char* kFormat = "ambdiag.run/1";
// Bounds that no real recording reaches; they keep sample arithmetic sane.
constexpr double kMaxSampleRateHz = 1e8;
constexpr double kMaxSpeedRpm = 1e6;
// A stepsine segment's meas_samples must hold `periods` whole periods to
// this relative accuracy (freq_hz is written with finite digits).
constexpr double kStepsinePeriodTolerance = 1e-6;

static_assert(sizeof(float) == 4 && std::numeric_limits<float>::is_iec559, "samples.f32 needs IEEE float32");

ChannelRole role_from_text(const std::string& s) {
  if (s == "reference") return ChannelRole::reference;
  if (s == "force") return ChannelRole::force;
  if (s == "displacement") return ChannelRole::displacement;
  if (s == "acceleration") return ChannelRole::acceleration;
  if (s == "velocity") return ChannelRole::velocity;
  if (s == "speed") return ChannelRole::speed;
  return ChannelRole::other;
}

// Unknown values are kept, but not nested without bound: copying, comparing
// and writing JSON recurse, and a hostile file must not exhaust the stack.
constexpr int kMaxExtraDepth = 64;

bool nested_deeper_than(const json& v, int levels) {
  if (!v.is_structured()) return false;
  if (levels == 0) return true;
  for (const json& x : v) {
    if (nested_deeper_than(x, levels - 1)) return true;
  }
  return false;
}

// The members of `obj` whose keys are not in `known`.
json extras_of(const JsonField& obj, std::initializer_list<const char*> known) {
  json extra = json::object();
  for (const auto& [key, value] : obj.raw().items()) {
    bool is_known = false;
    for (const char* k : known) is_known = is_known || key == k;
    if (is_known) continue;
    if (nested_deeper_than(value, kMaxExtraDepth)) {
      throw InputError((obj.path().empty() ? key : obj.path() + "." + key) + ": nested deeper than " +
                       std::to_string(kMaxExtraDepth) + " levels");
    }
    extra[key] = value;
  }
  return extra;
}

std::string segment_path(size_t i) { return "excitation.segments[" + std::to_string(i) + "]"; }

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw InputError(path + ": " + what);
}

// Last sample + 1 of a segment; fails if it does not fit in int64.
int64_t segment_end(const Excitation& ex, const ExcitationSegment& s, size_t i) {
  int64_t len = s.length;
  if (ex.type == ExcitationType::multisine && __builtin_mul_overflow(s.periods, ex.period_samples, &len)) {
    fail(segment_path(i), "periods x period_samples overflows");
  }
  int64_t end = 0;
  if (__builtin_add_overflow(s.start, len, &end)) fail(segment_path(i), "start + length overflows");
  return end;
}

void check_segment(const RunRecording& run, const Excitation& ex, const ExcitationSegment& s, size_t i) {
  const std::string p = segment_path(i);
  if (s.start < 0) fail(p + ".start", "must be >= 0");
  switch (ex.type) {
    case ExcitationType::multisine:
      if (s.periods <= 0) fail(p + ".periods", "must be > 0");
      if (s.settle_periods < 0) fail(p + ".settle_periods", "must be >= 0");
      if (s.settle_periods >= s.periods)
        fail(p + ".settle_periods", "must be < periods (nothing left to use)");
      if (s.pattern < 0) fail(p + ".pattern", "must be >= 0");
      break;
    case ExcitationType::stepsine: {
      if (s.length <= 0) fail(p + ".length", "must be > 0");
      if (s.input.empty()) fail(p + ".input", "must not be empty");
      bool driven = false;
      for (const Channel& c : run.channels)
        driven = driven || (c.role == ChannelRole::reference && c.input == s.input);
      if (!driven) fail(p + ".input", "'" + s.input + "' is the input of no reference channel");
      if (!std::isfinite(s.freq_hz) || s.freq_hz <= 0.0) fail(p + ".freq_hz", "must be > 0");
      if (s.freq_hz > run.sample_rate_hz / 2) fail(p + ".freq_hz", "must be <= sample_rate_hz / 2");
      if (!std::isfinite(s.amplitude) || s.amplitude <= 0.0) fail(p + ".amplitude", "must be > 0");
      if (s.settle_samples < 0) fail(p + ".settle_samples", "must be >= 0");
      if (s.meas_samples <= 0) fail(p + ".meas_samples", "must be > 0");
      if (s.periods <= 0) fail(p + ".periods", "must be > 0");
      if (s.settle_samples > s.length || s.meas_samples != s.length - s.settle_samples) {
        fail(p, "settle_samples + meas_samples (" + std::to_string(s.settle_samples) + " + " +
                    std::to_string(s.meas_samples) + ") must equal length (" + std::to_string(s.length) +
                    ")");
      }
      const double periods_held = static_cast<double>(s.meas_samples) * s.freq_hz / run.sample_rate_hz;
      if (std::fabs(periods_held - static_cast<double>(s.periods)) >
          kStepsinePeriodTolerance * static_cast<double>(s.periods)) {
        fail(p, "meas_samples hold " + std::to_string(periods_held) + " periods of freq_hz, not " +
                    std::to_string(s.periods) + " whole periods");
      }
      break;
    }
    case ExcitationType::chirp:
    case ExcitationType::random:
      if (s.length <= 0) fail(p + ".length", "must be > 0");
      break;
    case ExcitationType::none:
      break;
  }
  segment_end(ex, s, i);
}

// Every rule that does not need the samples.
void check_metadata(const RunRecording& run) {
  if (run.pump_id.empty()) fail("pump_id", "must not be empty");
  if (run.run_id.empty()) fail("run_id", "must not be empty");
  if (run.kind != "identification" && run.kind != "monitoring") {
    fail("kind", "must be identification or monitoring, not '" + run.kind + "'");
  }
  if (!std::isfinite(run.sample_rate_hz) || run.sample_rate_hz <= 0.0) fail("sample_rate_hz", "must be > 0");
  if (run.sample_rate_hz > kMaxSampleRateHz) fail("sample_rate_hz", "must be <= 1e8");
  if (!std::isfinite(run.speed_rpm) || run.speed_rpm < 0.0) fail("speed_rpm", "must be >= 0");
  if (run.speed_rpm > kMaxSpeedRpm) fail("speed_rpm", "must be <= 1e6");

  if (run.channels.empty()) fail("channels", "must not be empty");
  std::set<std::string> names;
  for (size_t i = 0; i < run.channels.size(); ++i) {
    const Channel& c = run.channels[i];
    const std::string p = "channels[" + std::to_string(i) + "]";
    if (c.name.empty()) fail(p + ".name", "must not be empty");
    if (!names.insert(c.name).second) fail(p + ".name", "duplicate channel name '" + c.name + "'");
    if (c.role == ChannelRole::reference && c.input.empty()) {
      fail(p + ".input", "missing (a reference channel names the actuator it drives)");
    }
  }

  if (!run.excitation) {
    if (run.kind == "identification") fail("excitation", "missing (required for kind identification)");
    return;
  }
  const Excitation& ex = *run.excitation;
  if (ex.type == ExcitationType::none)
    fail("excitation.type", "must be multisine, stepsine, chirp or random");
  if (!std::isfinite(ex.f_min_hz) || ex.f_min_hz < 0.0) fail("excitation.f_min_hz", "must be >= 0");
  if (!std::isfinite(ex.f_max_hz) || ex.f_max_hz <= ex.f_min_hz)
    fail("excitation.f_max_hz", "must be > f_min_hz");
  if (ex.f_max_hz > run.sample_rate_hz / 2) fail("excitation.f_max_hz", "must be <= sample_rate_hz / 2");
  if (ex.type == ExcitationType::multisine && ex.period_samples <= 0) {
    fail("excitation.period_samples", "must be > 0");
  }
  if (ex.segments.empty()) fail("excitation.segments", "must not be empty");
  for (size_t i = 0; i < ex.segments.size(); ++i) check_segment(run, ex, ex.segments[i], i);
}

ExcitationSegment segment_from_json(const JsonField& f, ExcitationType type) {
  f.require_object();
  ExcitationSegment s;
  s.start = f.at("start").integer();
  switch (type) {
    case ExcitationType::multisine: {
      s.periods = f.at("periods").integer();
      s.settle_periods = f.at("settle_periods").integer();
      const JsonField pattern = f.at("pattern");
      const int64_t p = pattern.integer();
      if (p < 0 || p > INT_MAX) pattern.fail("must be an integer in 0.." + std::to_string(INT_MAX));
      s.pattern = static_cast<int>(p);
      s.extra = extras_of(f, {"start", "periods", "settle_periods", "pattern"});
      break;
    }
    case ExcitationType::stepsine:
      s.length = f.at("length").integer();
      s.input = f.at("input").string();
      s.freq_hz = f.at("freq_hz").number();
      s.amplitude = f.at("amplitude").number();
      s.settle_samples = f.at("settle_samples").integer();
      s.meas_samples = f.at("meas_samples").integer();
      s.periods = f.at("periods").integer();
      s.extra = extras_of(f, {"start", "length", "input", "freq_hz", "amplitude", "settle_samples",
                              "meas_samples", "periods"});
      break;
    default:
      s.length = f.at("length").integer();
      s.extra = extras_of(f, {"start", "length"});
      break;
  }
  return s;
}

Excitation excitation_from_json(const JsonField& f) {
  f.require_object();
  Excitation ex;
  const JsonField type = f.at("type");
  const std::string t = type.string();
  if (t == "multisine") {
    ex.type = ExcitationType::multisine;
  } else if (t == "stepsine") {
    ex.type = ExcitationType::stepsine;
  } else if (t == "chirp") {
    ex.type = ExcitationType::chirp;
  } else if (t == "random") {
    ex.type = ExcitationType::random;
  } else {
    type.fail("must be multisine, stepsine, chirp or random, not '" + t + "'");
  }
  if (ex.type == ExcitationType::multisine) ex.period_samples = f.at("period_samples").integer();
  ex.f_min_hz = f.at("f_min_hz").number();
  ex.f_max_hz = f.at("f_max_hz").number();
  const JsonField segments = f.at("segments");
  const size_t n = segments.size();
  ex.segments.reserve(n);
  for (size_t i = 0; i < n; ++i) ex.segments.push_back(segment_from_json(segments.at(i), ex.type));
  if (ex.type == ExcitationType::multisine) {
    ex.extra = extras_of(f, {"type", "period_samples", "f_min_hz", "f_max_hz", "segments"});
  } else {
    ex.extra = extras_of(f, {"type", "f_min_hz", "f_max_hz", "segments"});
  }
  return ex;
}

json segment_to_json(const ExcitationSegment& s, ExcitationType type) {
  json j = s.extra.is_object() ? s.extra : json::object();
  j["start"] = s.start;
  switch (type) {
    case ExcitationType::multisine:
      j["periods"] = s.periods;
      j["settle_periods"] = s.settle_periods;
      j["pattern"] = s.pattern;
      break;
    case ExcitationType::stepsine:
      j["length"] = s.length;
      j["input"] = s.input;
      j["freq_hz"] = s.freq_hz;
      j["amplitude"] = s.amplitude;
      j["settle_samples"] = s.settle_samples;
      j["meas_samples"] = s.meas_samples;
      j["periods"] = s.periods;
      break;
    default:
      j["length"] = s.length;
      break;
  }
  return j;
}

uint32_t byteswap32(uint32_t v) {
  return (v >> 24) | ((v >> 8) & 0xFF00u) | ((v << 8) & 0xFF0000u) | (v << 24);
}

// Decodes float32 little-endian into `out` in place (a no-op on little-endian machines).
void from_little_endian(std::span<float> v) {
  if constexpr (std::endian::native == std::endian::big) {
    for (float& x : v) {
      uint32_t u;
      std::memcpy(&u, &x, 4);
      u = byteswap32(u);
      std::memcpy(&x, &u, 4);
    }
  }
}

std::string to_little_endian_bytes(const std::vector<float>& v) {
  std::string bytes(v.size() * 4, '\0');
  if (!v.empty()) std::memcpy(bytes.data(), v.data(), bytes.size());
  if constexpr (std::endian::native == std::endian::big) {
    for (size_t i = 0; i < v.size(); ++i) {
      uint32_t u;
      std::memcpy(&u, bytes.data() + 4 * i, 4);
      u = byteswap32(u);
      std::memcpy(bytes.data() + 4 * i, &u, 4);
    }
  }
  return bytes;
}

// True if any value is NaN or infinite (exponent bits all ones). The flags
// are or-ed in fixed groups of 16 so that GCC's -O2 vectoriser (the
// "very cheap" cost model, which wants known trip counts) takes the inner
// loop: 3 x faster than a scalar loop, which was a quarter of a replaying
// agent's CPU.
bool any_non_finite(std::span<const float> v) {
  constexpr uint32_t kExponent = 0x7f800000u;
  constexpr size_t kGroup = 16;
  const size_t whole = v.size() / kGroup * kGroup;
  uint32_t bad = 0;
  for (size_t i = 0; i < whole; i += kGroup) {
    uint32_t bits[kGroup];
    std::memcpy(bits, v.data() + i, sizeof bits);
    uint32_t g = 0;
    for (size_t k = 0; k < kGroup; ++k) g |= (bits[k] & kExponent) == kExponent ? 1u : 0u;
    bad |= g;
  }
  for (size_t i = whole; i < v.size(); ++i) bad |= (std::bit_cast<uint32_t>(v[i]) & kExponent) == kExponent ? 1u : 0u;
  return bad != 0;
}

// Names the first non-finite value of `v` (interleaved frames of
// `channels`, starting at value index `offset`), or returns normally.
void check_finite(std::span<const float> v, size_t offset, const std::vector<Channel>& channels,
                  const std::string& what) {
  if (!any_non_finite(v)) return;
  const size_t nch = channels.size();
  for (size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i])) {
      throw InputError(what + ": frame " + std::to_string((offset + i) / nch) + ", channel " +
                       channels[(offset + i) % nch].name + ": NaN or infinite sample");
    }
  }
}

// Reads samples.f32 and checks every value as it comes in: each piece is
// checked while it is still in cache, so the file costs one pass over
// memory, not two (the machine's memory bandwidth bounds a replaying agent).
std::vector<float> read_samples(const std::string& path, const std::vector<Channel>& channels) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw InputError(path + ": cannot open (" + std::strerror(errno) + ")");
  const std::streamoff size = in.tellg();
  if (size < 0) throw InputError(path + ": cannot determine the size");
  const auto bytes = static_cast<uint64_t>(size);
  const uint64_t frame_bytes = 4 * static_cast<uint64_t>(channels.size());
  if (bytes % frame_bytes != 0) {
    throw InputError(path + ": " + std::to_string(bytes) + " bytes is not a whole number of frames (" +
                     std::to_string(channels.size()) + " channels x 4 bytes)");
  }
  std::vector<float> samples(bytes / 4);
  in.seekg(0);
  constexpr size_t kPiece = size_t{64} << 10;  // values: 256 KiB, well inside L2
  for (size_t at = 0; at < samples.size(); at += kPiece) {
    const size_t n = std::min(kPiece, samples.size() - at);
    if (!in.read(reinterpret_cast<char*>(samples.data() + at), static_cast<std::streamsize>(n * 4)))
      throw InputError(path + ": read error");
    std::span<float> piece(samples.data() + at, n);
    from_little_endian(piece);
    check_finite(piece, at, channels, path);
  }
  return samples;
}

}  // namespace

std::string to_string(ChannelRole r) {
  switch (r) {
    case ChannelRole::reference:
      return "reference";
    case ChannelRole::force:
      return "force";
    case ChannelRole::displacement:
      return "displacement";
    case ChannelRole::acceleration:
      return "acceleration";
    case ChannelRole::velocity:
      return "velocity";
    case ChannelRole::speed:
      return "speed";
    case ChannelRole::other:
      return "other";
  }
  return "other";
}

std::string to_string(ExcitationType t) {
  switch (t) {
    case ExcitationType::multisine:
      return "multisine";
    case ExcitationType::stepsine:
      return "stepsine";
    case ExcitationType::chirp:
      return "chirp";
    case ExcitationType::random:
      return "random";
    case ExcitationType::none:
      return "none";
  }
  return "none";
}

int64_t RunRecording::frame_count() const {
  if (channels.empty()) return 0;
  return static_cast<int64_t>(samples.size() / channels.size());
}

int RunRecording::channel_index(const std::string& name) const {
  for (size_t i = 0; i < channels.size(); ++i) {
    if (channels[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

void RunRecording::validate() const {
  validate_structure();
  check_finite(samples, 0, channels, "samples");
}

void RunRecording::validate_structure() const {
  check_metadata(*this);
  const size_t nch = channels.size();
  if (samples.size() % nch != 0) {
    fail("samples", std::to_string(samples.size()) + " values are not a whole number of frames of " +
                        std::to_string(nch) + " channels");
  }
  if (samples.empty()) fail("samples", "no frames");
  if (excitation) {
    const int64_t frames = frame_count();
    for (size_t i = 0; i < excitation->segments.size(); ++i) {
      const int64_t end = segment_end(*excitation, excitation->segments[i], i);
      if (end > frames) {
        fail(segment_path(i), "ends at sample " + std::to_string(end) + ", past the end of the recording (" +
                                  std::to_string(frames) + " frames)");
      }
    }
  }
}

void RunRecording::validate_against(const PlantModel& plant) const {
  // Plain loops over the plant's lists: the channel names are few.
  const auto is_actuator = [&](const std::string& n) {
    for (const auto& a : plant.actuators) {
      if (a.name == n) return true;
    }
    return false;
  };
  const auto is_sensor = [&](const std::string& n) {
    for (const auto& s : plant.sensors) {
      if (s.name == n) return true;
    }
    return false;
  };
  const std::string model = "plant model '" + plant.name + "'";
  for (size_t i = 0; i < channels.size(); ++i) {
    const Channel& c = channels[i];
    const std::string p = "channels[" + std::to_string(i) + "] (" + c.name + ")";
    switch (c.role) {
      case ChannelRole::reference:
        if (!is_actuator(c.input)) fail(p, "input '" + c.input + "' is not an actuator of the " + model);
        break;
      case ChannelRole::force:
        if (!is_actuator(c.name)) fail(p, "a force channel must be named after an actuator of the " + model);
        break;
      case ChannelRole::displacement:
        if (!is_sensor(c.name))
          fail(p, "a displacement channel must be named after a sensor of the " + model);
        break;
      default:
        break;  // acceleration, velocity, speed, other: rigs without a plant model name these freely
    }
  }
}

RunRecording run_from_json(const nlohmann::json& doc) {
  if (!doc.is_object()) throw InputError("run.json: must be a JSON object");
  const JsonField root(doc, "");
  RunRecording run;
  const JsonField format = root.at("format");
  if (format.string() != kFormat) format.fail(std::string("must be \"") + kFormat + "\"");
  run.pump_id = root.at("pump_id").string();
  run.run_id = root.at("run_id").string();
  run.kind = root.at("kind").string();
  run.started_at = root.at("started_at").string();
  run.speed_rpm = root.at("speed_rpm").number();
  run.sample_rate_hz = root.at("sample_rate_hz").number();

  const JsonField channels = root.at("channels");
  const size_t n = channels.size();
  run.channels.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    const JsonField c = channels.at(i);
    c.require_object();
    Channel ch;
    ch.name = c.at("name").string();
    ch.role_text = c.at("role").string();
    ch.role = role_from_text(ch.role_text);
    ch.unit = c.at("unit").string();
    if (ch.role == ChannelRole::reference) {
      if (!c.has("input")) c.fail("a reference channel needs 'input' (the actuator it drives)");
      ch.input = c.at("input").string();
      ch.extra = extras_of(c, {"name", "role", "unit", "input"});
    } else {
      ch.extra = extras_of(c, {"name", "role", "unit"});
    }
    run.channels.push_back(std::move(ch));
  }
  if (auto ex = root.opt("excitation")) run.excitation = excitation_from_json(*ex);
  run.extra = extras_of(root, {"format", "pump_id", "run_id", "kind", "started_at", "speed_rpm",
                               "sample_rate_hz", "channels", "excitation"});
  check_metadata(run);
  return run;
}

nlohmann::json run_to_json(const RunRecording& run) {
  json j = run.extra.is_object() ? run.extra : json::object();
  j["format"] = kFormat;
  j["pump_id"] = run.pump_id;
  j["run_id"] = run.run_id;
  j["kind"] = run.kind;
  j["started_at"] = run.started_at;
  j["speed_rpm"] = run.speed_rpm;
  j["sample_rate_hz"] = run.sample_rate_hz;
  json channels = json::array();
  for (const Channel& c : run.channels) {
    json cj = c.extra.is_object() ? c.extra : json::object();
    cj["name"] = c.name;
    cj["role"] = (c.role == ChannelRole::other && !c.role_text.empty()) ? c.role_text : to_string(c.role);
    cj["unit"] = c.unit;
    if (c.role == ChannelRole::reference) cj["input"] = c.input;
    channels.push_back(std::move(cj));
  }
  j["channels"] = std::move(channels);
  if (run.excitation) {
    const Excitation& ex = *run.excitation;
    json e = ex.extra.is_object() ? ex.extra : json::object();
    e["type"] = to_string(ex.type);
    if (ex.type == ExcitationType::multisine) e["period_samples"] = ex.period_samples;
    e["f_min_hz"] = ex.f_min_hz;
    e["f_max_hz"] = ex.f_max_hz;
    json segments = json::array();
    for (const auto& s : ex.segments) segments.push_back(segment_to_json(s, ex.type));
    e["segments"] = std::move(segments);
    j["excitation"] = std::move(e);
  } else {
    j.erase("excitation");
  }
  return j;
}

RunRecording read_run(const std::string& dir) {
  namespace fs = std::filesystem;
  const std::string json_path = (fs::path(dir) / "run.json").string();
  const std::string samples_path = (fs::path(dir) / "samples.f32").string();
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw InputError(dir + ": not a run folder (no such directory)");
  for (const std::string& p : {json_path, samples_path}) {
    if (!fs::is_regular_file(p, ec))
      throw InputError(p + ": missing (a run folder holds run.json and samples.f32)");
  }

  RunRecording run;
  try {
    run = run_from_json(detail::parse_json_text(read_file_bytes(json_path), json_path));
  } catch (const InputError& e) {
    if (std::string_view(e.what()).starts_with(json_path)) throw;
    rethrow_with_context(e, json_path);
  }
  run.samples = read_samples(samples_path, run.channels);  // every value checked on the way in
  try {
    run.validate_structure();
  } catch (const InputError& e) {
    rethrow_with_context(e, dir);
  }
  return run;
}

void write_run(const std::string& dir, const RunRecording& run) {
  run.validate();
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw InputError(dir + ": cannot create the run folder (" + ec.message() + ")");
  // samples first: a reader that finds the new run.json also finds its samples.
  write_file_atomic((fs::path(dir) / "samples.f32").string(), to_little_endian_bytes(run.samples));
  write_file_atomic((fs::path(dir) / "run.json").string(), run_to_json(run).dump(2) + "\n");
}

}  // namespace ambdiag
