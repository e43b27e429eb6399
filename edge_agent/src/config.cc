#include "ambdiag/edge_agent/config.h"

#include <cmath>
#include <optional>
#include <set>

#include <nlohmann/json.hpp>

#include "ambdiag/core/checksum.h"
#include "ambdiag/core/error.h"
#include "ambdiag/core/io_util.h"
#include "ambdiag/edge_agent/simulate.h"
#include "ambdiag/proto/stream.h"

namespace ambdiag::agent {
namespace {

using nlohmann::json;

struct Reader {
  const std::string& file;
  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw InputError(file + ": " + key + ": " + what);
  }
  void only(const json& obj, const std::string& where, const std::set<std::string>& keys) const {
    if (!obj.is_object()) fail(where.empty() ? "(top level)" : where, "must be an object");
    for (const auto& [k, v] : obj.items())
      if (!keys.count(k)) fail(where.empty() ? k : where + "." + k, "unknown key");
  }
  std::string str(const json& v, const std::string& key) const {
    if (!v.is_string() || v.get<std::string>().empty()) fail(key, "must be a non-empty string");
    return v.get<std::string>();
  }
  double number(const json& v, const std::string& key) const {
    if (!v.is_number() || !std::isfinite(v.get<double>())) fail(key, "must be a number");
    return v.get<double>();
  }
  int64_t integer(const json& v, const std::string& key) const {
    if (!v.is_number_integer()) fail(key, "must be an integer");
    return v.get<int64_t>();
  }
};

}  // namespace

void validate(const AgentConfig& c, const std::string& origin) {
  auto fail = [&](const std::string& key, const std::string& what) { throw InputError(origin + ": " + key + ": " + what); };
  if (c.source != "replay" && c.source != "simulate") fail("source", "must be \"replay\" or \"simulate\"");
  if (c.domain < 0 || c.domain > 232) fail("dds.domain", "must be in 0..232");
  if (c.partition.empty() || c.partition.find_first_of("*?[]") != std::string::npos)
    fail("dds.partition", "must be a plain name (no wildcards)");
  if (!(c.identification_interval_s > 0)) fail("schedule.identification_interval_s", "must be > 0");
  if (!(c.monitoring_interval_s >= 0)) fail("schedule.monitoring_interval_s", "must be >= 0 (0: no snapshots)");
  if (c.runs < 0) fail("schedule.runs", "must be >= 0 (0: no limit)");
  const SimulationConfig& s = c.simulation;
  if (s.excitation != "multisine" && s.excitation != "stepsine") fail("simulation.excitation", "must be \"multisine\" or \"stepsine\"");
  if (!(s.sample_rate_hz >= 64 && s.sample_rate_hz <= 1e6)) fail("simulation.sample_rate_hz", "must be in 64..1e6");
  if (s.period_samples < 64 || s.period_samples > (1 << 22)) fail("simulation.period_samples", "must be in 64..4194304");
  if (!(s.f_min_hz > 0)) fail("simulation.f_min_hz", "must be > 0");
  if (!(s.f_max_hz > s.f_min_hz && s.f_max_hz < s.sample_rate_hz / 2)) fail("simulation.f_max_hz", "must be in (f_min_hz, sample_rate_hz / 2)");
  if (s.settle_periods < 0 || s.settle_periods > 1000) fail("simulation.settle_periods", "must be in 0..1000");
  if (s.meas_periods < 1 || s.meas_periods > 1000) fail("simulation.meas_periods", "must be in 1..1000");
  if (!(s.monitoring_s > 0 && s.monitoring_s <= 3600)) fail("simulation.monitoring_s", "must be in (0, 3600]");
  if (!(s.speed_spread_pct >= 0 && s.speed_spread_pct <= 20)) fail("simulation.speed_spread_pct", "must be in 0..20");
  if (!(s.seal_drift_pct >= 0 && s.seal_drift_pct <= 20)) fail("simulation.seal_drift_pct", "must be in 0..20");
  if (!(s.seal_drift_link_pct >= 0 && s.seal_drift_link_pct <= 20)) fail("simulation.seal_drift_link_pct", "must be in 0..20");
  for (size_t i = 0; i < s.faults.size(); ++i) {
    try {
      parse_fault_schedule(s.faults[i]);
    } catch (const InputError& e) {
      fail("simulation.faults[" + std::to_string(i) + "]", e.what());
    }
  }
  if (c.spool_dir.empty()) fail("spool.dir", "must be a folder");
  if (c.spool_limit_bytes < (1u << 20)) fail("spool.limit_bytes", "must be at least 1 MiB (1048576)");
  if (c.memory_blocks < 1 || c.memory_blocks > 65536) fail("spool.memory_blocks", "must be in 1..65536");
  if (c.block_frames < 1 || c.block_frames > 65536) fail("block_frames", "must be in 1..65536");
}

AgentConfig load_agent_config(const std::string& path) {
  const std::string text = read_file_bytes(path);
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::parse_error& e) {
    throw InputError(path + ": not valid JSON: " + e.what());
  }
  const Reader r{path};
  r.only(doc, "", {"pump_id", "model", "source", "schedule", "simulation", "dds", "spool", "block_frames"});
  AgentConfig c;
  if (doc.contains("pump_id")) c.pump_id = r.str(doc["pump_id"], "pump_id");
  if (doc.contains("model")) c.model = r.str(doc["model"], "model");
  if (doc.contains("source")) c.source = r.str(doc["source"], "source");
  if (doc.contains("schedule")) {
    const json& s = doc["schedule"];
    r.only(s, "schedule", {"identification_interval_s", "monitoring_interval_s", "runs"});
    if (s.contains("runs")) c.runs = r.integer(s["runs"], "schedule.runs");
    if (s.contains("identification_interval_s"))
      c.identification_interval_s = r.number(s["identification_interval_s"], "schedule.identification_interval_s");
    if (s.contains("monitoring_interval_s"))
      c.monitoring_interval_s = r.number(s["monitoring_interval_s"], "schedule.monitoring_interval_s");
  }
  if (doc.contains("simulation")) {
    const json& s = doc["simulation"];
    SimulationConfig& m = c.simulation;
    r.only(s, "simulation", {"excitation", "faults", "sample_rate_hz", "period_samples", "f_min_hz", "f_max_hz",
                             "settle_periods", "meas_periods", "monitoring_s", "seed", "speed_spread_pct",
                             "seal_drift_pct", "seal_drift_link_pct"});
    if (s.contains("excitation")) m.excitation = r.str(s["excitation"], "simulation.excitation");
    if (s.contains("faults")) {
      if (!s["faults"].is_array()) r.fail("simulation.faults", "must be a list of fault names");
      for (size_t i = 0; i < s["faults"].size(); ++i)
        m.faults.push_back(r.str(s["faults"][i], "simulation.faults[" + std::to_string(i) + "]"));
    }
    auto num = [&](const char* k, double& out) {
      if (s.contains(k)) out = r.number(s[k], std::string("simulation.") + k);
    };
    auto whole = [&](const char* k, int64_t lo, int64_t hi) -> std::optional<int64_t> {
      if (!s.contains(k)) return std::nullopt;
      const int64_t v = r.integer(s[k], std::string("simulation.") + k);
      if (v < lo || v > hi) r.fail(std::string("simulation.") + k, "must be in " + std::to_string(lo) + ".." + std::to_string(hi));
      return v;
    };
    num("sample_rate_hz", m.sample_rate_hz);
    num("f_min_hz", m.f_min_hz);
    num("f_max_hz", m.f_max_hz);
    num("monitoring_s", m.monitoring_s);
    num("speed_spread_pct", m.speed_spread_pct);
    num("seal_drift_pct", m.seal_drift_pct);
    num("seal_drift_link_pct", m.seal_drift_link_pct);
    if (auto v = whole("period_samples", 64, 1 << 22)) m.period_samples = *v;
    if (auto v = whole("settle_periods", 0, 1000)) m.settle_periods = static_cast<int>(*v);
    if (auto v = whole("meas_periods", 1, 1000)) m.meas_periods = static_cast<int>(*v);
    if (auto v = whole("seed", 0, int64_t{1} << 40)) m.seed = static_cast<uint64_t>(*v);
  }
  if (doc.contains("dds")) {
    const json& d = doc["dds"];
    r.only(d, "dds", {"domain", "partition", "partition_per_pump", "checksum", "protocol"});
    if (d.contains("domain")) {
      const int64_t v = r.integer(d["domain"], "dds.domain");
      if (v < 0 || v > 232) r.fail("dds.domain", "must be in 0..232");
      c.domain = static_cast<int>(v);
    }
    if (d.contains("partition")) c.partition = r.str(d["partition"], "dds.partition");
    if (d.contains("partition_per_pump")) {
      if (!d["partition_per_pump"].is_boolean()) r.fail("dds.partition_per_pump", "must be true or false");
      c.partition_per_pump = d["partition_per_pump"].get<bool>();
    }
    if (d.contains("checksum")) {
      c.checksum = r.str(d["checksum"], "dds.checksum");
      if (!checksum_kind_from(c.checksum)) r.fail("dds.checksum", "must be \"xxh64\" or \"fnv1a64\"");
    }
    if (d.contains("protocol")) {
      c.protocol = r.str(d["protocol"], "dds.protocol");
      const auto minor = stream::minor_of(c.protocol);
      if (!minor || *minor < 1)
        r.fail("dds.protocol", "must be \"1.1\" or \"" + stream::version_string(stream::kProtocolVersion) + "\"");
    }
  }
  if (doc.contains("spool")) {
    const json& s = doc["spool"];
    r.only(s, "spool", {"dir", "limit_bytes", "memory_blocks"});
    if (s.contains("dir")) c.spool_dir = r.str(s["dir"], "spool.dir");
    if (s.contains("limit_bytes")) {
      const int64_t v = r.integer(s["limit_bytes"], "spool.limit_bytes");
      if (v < 0) r.fail("spool.limit_bytes", "must be >= 0");
      c.spool_limit_bytes = static_cast<uint64_t>(v);
    }
    if (s.contains("memory_blocks")) {
      const int64_t v = r.integer(s["memory_blocks"], "spool.memory_blocks");
      if (v < 1 || v > 65536) r.fail("spool.memory_blocks", "must be in 1..65536");
      c.memory_blocks = static_cast<uint32_t>(v);
    }
  }
  if (doc.contains("block_frames")) {
    const int64_t v = r.integer(doc["block_frames"], "block_frames");
    if (v < 1 || v > 65536) r.fail("block_frames", "must be in 1..65536");
    c.block_frames = static_cast<uint32_t>(v);
  }
  validate(c, path);
  return c;
}

std::string dds_partition(const AgentConfig& c, const std::string& origin) {
  if (!c.partition_per_pump) return c.partition;
  if (c.pump_id.empty()) throw InputError(origin + ": dds.partition_per_pump needs the pump id (--pump ID or \"pump_id\")");
  if (!stream::plain_partition_name(c.pump_id))
    throw InputError(origin + ": pump_id '" + c.pump_id + "' cannot name a partition (dds.partition_per_pump): no / * ? [ ] \\");
  if (!stream::plain_partition_name(c.partition))
    throw InputError(origin + ": dds.partition '" + c.partition + "' must not contain / with dds.partition_per_pump");
  return stream::pump_partition(c.partition, c.pump_id);
}

}  // namespace ambdiag::agent
