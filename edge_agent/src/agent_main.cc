// ambdiag-agent: the edge agent (../shared/specs/cli.md).
//   ambdiag-agent replay RUN_DIR [--fast] [--domain D] [options]
// Exit codes: 0 every sample committed and verified by the server, 1 not
// (timeout, server verdict incomplete, stopped), 2 usage error, 3 bad input.
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <exception>
#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "ambdiag/core/error.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/process_memory.h"
#include "ambdiag/core/run_recording.h"
#include "ambdiag/edge_agent/block_source.h"
#include "ambdiag/edge_agent/config.h"
#include "ambdiag/edge_agent/monitoring.h"
#include "ambdiag/edge_agent/schedule.h"
#include "ambdiag/edge_agent/simulate.h"
#include "ambdiag/edge_agent/spool.h"
#include "ambdiag/edge_agent/streamer.h"
#include "ambdiag/proto/dds.h"

namespace {

using namespace ambdiag;

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) { g_stop = true; }

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

const char* kUsage =
    "usage: ambdiag-agent replay RUN_DIR [--fast] [--domain D] [options]\n"
    "       ambdiag-agent simulate --model PLANT.json --pump ID [--fault NAME ...] [--fast] [--domain D] [options]\n"
    "       ambdiag-agent forward [--spool-dir DIR] [--domain D] [options]\n"
    "\n"
    "Streams runs over Cyclone DDS to `ambdiag serve`; exits 0 once every sample is\n"
    "acknowledged durable (on the server's disk for good; protocol 1.2) and the server\n"
    "verified the run's count and checksum.\n"
    "Runs left in the spool by an earlier agent (killed, restarted) are sent first;\n"
    "`forward` sends only those.\n"
    "\n"
    "options:\n"
    "  --config FILE        agent configuration (JSON; see edge_agent/README.md)\n"
    "  --fast               replay, simulate: stream as fast as possible (default: paced at\n"
    "                       the sample rate, so a default simulated run of 30 s takes 30 s)\n"
    "  --domain D           DDS domain id (default 0 or the config's)\n"
    "  --partition NAME     DDS partition, one per site (default \"site\")\n"
    "  --partition-per-pump publish in the pump's own partition NAME/PUMP (what DDS Security\n"
    "                       permissions grant an enrolled agent; needs --pump ID)\n"
    "  --pump ID            pump id (default: the recording's)\n"
    "  --spool-dir DIR      store-and-forward folder (default ./ambdiag-spool), one agent per folder\n"
    "  --spool-limit BYTES  bound on the spool's disk use (default 1 GiB)\n"
    "  --block-frames N     frames per sample block (default 512)\n"
    "  --timeout S          give up after S seconds without progress (default 60)\n"
    "  --runs N             simulate: identification runs, then exit (default: the config's\n"
    "                       schedule.runs; 0 = until stopped)\n"
    "  --fault SPEC ...     simulate: inject faults, NAME[=V|=A..B][@runK[..M]]: V from\n"
    "                       run 1 (or K) on, healthy before; A..B linear to the last run\n"
    "                       (of --runs N, or M); see docs/simulation.md\n"
    "  --speed-spread PCT   simulate: each run at the model speed x (1 + U(-PCT, PCT) / 100)\n"
    "                       (default 0; 0..20)\n"
    "  --seal-drift PCT     simulate: per run, seal and balance-piston coefficients x (1 + d),\n"
    "                       d ~ N(0, PCT / 100) common to the links (default 0; 0..20)\n"
    "  --seal-drift-link PCT  simulate: plus an independent N(0, PCT / 100) per link (default 0)\n"
    "  --seed N             simulate: noise and variability seed (default 1)\n"
    "exit codes: 0 committed, 1 not committed (timeout, incomplete, stopped), 2 usage, 3 bad input\n";

struct Cli {
  std::string command;
  std::vector<std::string> positional;
  std::map<std::string, std::vector<std::string>> opts;
  std::map<std::string, bool> flags;
  std::string opt(const std::string& k, const std::string& def = "") const {
    auto it = opts.find(k);
    return it == opts.end() ? def : it->second.back();
  }
  bool has(const std::string& k) const { return opts.count(k) > 0; }
};

Cli parse(int argc, char** argv) {
  static const std::vector<std::string> kOptions = {"--config", "--domain", "--partition", "--pump", "--spool-dir",
                                                    "--spool-limit", "--block-frames", "--timeout", "--model",
                                                    "--runs", "--seed", "--speed-spread", "--seal-drift",
                                                    "--seal-drift-link"};
  Cli c;
  if (argc < 2) throw UsageError("missing command (replay, simulate or forward)");
  c.command = argv[1];
  if (c.command != "replay" && c.command != "simulate" && c.command != "forward")
    throw UsageError("unknown command '" + c.command + "'");
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--fast" || a == "--partition-per-pump") {
      c.flags[a] = true;
    } else if (a == "--fault") {  // --fault NAME [NAME ...]
      if (i + 1 >= argc || std::string(argv[i + 1]).starts_with("--")) throw UsageError("--fault needs a name");
      while (i + 1 < argc && !std::string(argv[i + 1]).starts_with("--")) c.opts[a].push_back(argv[++i]);
    } else if (std::find(kOptions.begin(), kOptions.end(), a) != kOptions.end()) {
      if (i + 1 >= argc) throw UsageError(a + " needs a value");
      c.opts[a].push_back(argv[++i]);
    } else if (a.starts_with("--")) {
      throw UsageError("unknown option " + a);
    } else {
      c.positional.push_back(a);
    }
  }
  return c;
}

long long integer_option(const Cli& c, const std::string& k, long long lo, long long hi) {
  const std::string v = c.opt(k);
  char* end = nullptr;
  errno = 0;
  const long long x = std::strtoll(v.c_str(), &end, 10);
  if (v.empty() || *end != '\0' || errno != 0 || x < lo || x > hi)
    throw UsageError(k + " must be an integer in " + std::to_string(lo) + ".." + std::to_string(hi) + ", got '" + v + "'");
  return x;
}

double percent_option(const Cli& c, const std::string& k) {
  const std::string v = c.opt(k);
  char* end = nullptr;
  const double x = std::strtod(v.c_str(), &end);
  if (v.empty() || *end != '\0' || !(x >= 0 && x <= 20)) throw UsageError(k + " must be a percentage in 0..20, got '" + v + "'");
  return x;
}

agent::AgentConfig config_from(const Cli& c) {
  agent::AgentConfig cfg = c.has("--config") ? agent::load_agent_config(c.opt("--config")) : agent::AgentConfig{};
  if (c.has("--domain")) cfg.domain = static_cast<int>(integer_option(c, "--domain", 0, 232));
  if (c.has("--partition")) cfg.partition = c.opt("--partition");
  if (c.flags.count("--partition-per-pump")) cfg.partition_per_pump = true;
  if (c.has("--pump")) cfg.pump_id = c.opt("--pump");
  if (c.has("--spool-dir")) cfg.spool_dir = c.opt("--spool-dir");
  if (c.has("--spool-limit")) cfg.spool_limit_bytes = static_cast<uint64_t>(integer_option(c, "--spool-limit", 0, 1ll << 50));
  if (c.has("--block-frames")) cfg.block_frames = static_cast<uint32_t>(integer_option(c, "--block-frames", 1, 65536));
  if (c.has("--model")) cfg.model = c.opt("--model");
  validate(cfg, "command line");
  agent::dds_partition(cfg, "command line");  // checked now, before any run is read
  return cfg;
}

// The agent's DDS side. Under DDS Security a writer or reader its
// permissions do not grant cannot be created: say which grant is missing
// (bad input, exit 3) rather than a bare return code.
std::unique_ptr<stream::AgentEndpoints> open_endpoints(const agent::AgentConfig& cfg) {
  const std::string partition = agent::dds_partition(cfg, "command line");
  try {
    return std::make_unique<stream::AgentEndpoints>(cfg.domain, partition);
  } catch (const dds::DdsError& e) {
    if (e.code() != DDS_RETCODE_NOT_ALLOWED_BY_SECURITY) throw;
    throw InputError("DDS Security refused this agent's endpoints (" + std::string(e.what()) +
                     "): its permissions document must grant publishing the ambdiag data topics and reading "
                     "ambdiag_Ack in partition '" + partition + "' of domain " + std::to_string(cfg.domain) +
                     "; enrol the agent for this pump (deploy/security/ambdiag-pki.sh agent DIR PUMP_ID) and "
                     "run it with that pump's security.xml and agent.json");
  }
}

std::string join(const std::vector<std::string>& v) {
  std::string out;
  for (const auto& s : v) out += (out.empty() ? "" : ", ") + s;
  return out;
}

// Streams one run; returns true if the server verified it complete.
bool stream_one(stream::AgentEndpoints& ep, RunRecording run, const agent::AgentConfig& cfg,
                const agent::StreamOptions& opt) {
  const std::string pump = cfg.pump_id.empty() ? run.pump_id : cfg.pump_id;
  const std::string run_id = run.run_id;
  std::fprintf(stderr, "ambdiag-agent: run %s of pump %s: %lld frames x %zu channels at %g Hz, %s\n", run_id.c_str(),
               pump.c_str(), static_cast<long long>(run.frame_count()), run.channels.size(), run.sample_rate_hz,
               opt.paced ? "paced" : "as fast as possible");
  agent::RecordingSource src(std::move(run), cfg.block_frames);
  agent::Spool spool(cfg.spool_dir, run_id, cfg.spool_limit_bytes, cfg.memory_blocks);
  const agent::StreamResult r = agent::stream_run(ep, src, spool, pump, opt);
  std::fprintf(stderr,
               "ambdiag-agent: run %s: %s: %s (%lld blocks, %lld frames, checksum %s %016llx, %lld sent, %lld resends, "
               "%lld acknowledged durable, spool peak %llu bytes)\n",
               run_id.c_str(), r.complete ? "committed" : "NOT committed", r.message.c_str(),
               static_cast<long long>(r.n_blocks), static_cast<long long>(r.total_frames), to_string(opt.checksum_kind),
               static_cast<unsigned long long>(r.checksum), static_cast<long long>(r.blocks_sent),
               static_cast<long long>(r.resends), static_cast<long long>(r.blocks_durable),
               static_cast<unsigned long long>(r.max_spool_disk_bytes));
  return r.complete;
}

// Sends the runs an earlier agent left in the spool (docs/streaming.md,
// "Store-and-forward"); true if there were none or the server verified all.
bool forward_backlog(stream::AgentEndpoints& ep, const agent::AgentConfig& cfg, const agent::StreamOptions& opt) {
  bool all_ok = true;
  for (const auto& dir : agent::Spool::pending_runs(cfg.spool_dir)) {
    std::vector<std::string> problems;
    std::unique_ptr<agent::Spool> spool;
    try {
      spool = agent::Spool::recover(dir, cfg.spool_limit_bytes, cfg.memory_blocks, problems);
    } catch (const std::exception& e) {  // InputError, filesystem_error
      std::fprintf(stderr, "ambdiag-agent: spool: %s: left in place\n", e.what());
      all_ok = false;
      continue;
    }
    for (const auto& p : problems) std::fprintf(stderr, "ambdiag-agent: spool: %s\n", p.c_str());
    const std::string run_id = spool->header()->run_id;
    if (cfg.partition_per_pump && spool->header()->pump_id != cfg.pump_id) {
      std::fprintf(stderr, "ambdiag-agent: spooled run %s is of pump %s, this agent publishes for pump %s only: left in place\n",
                   run_id.c_str(), spool->header()->pump_id.c_str(), cfg.pump_id.c_str());
      all_ok = false;
      continue;
    }
    std::fprintf(stderr, "ambdiag-agent: forwarding spooled run %s: %zu blocks held, %s\n", run_id.c_str(),
                 spool->size(), spool->end() ? "complete recording" : "cut off (no run end)");
    const agent::StreamResult r = agent::forward_spooled(ep, *spool, opt);
    std::fprintf(stderr, "ambdiag-agent: spooled run %s: %s: %s (%lld blocks, %lld sent)\n", run_id.c_str(),
                 r.complete ? "committed" : "NOT committed", r.message.c_str(), static_cast<long long>(r.n_blocks),
                 static_cast<long long>(r.blocks_sent));
    all_ok = r.complete && all_ok;
    if (g_stop) break;
    if (!r.server_verdict) {  // no server: do not wait out every spooled run in turn
      std::fprintf(stderr, "ambdiag-agent: spooled runs left for the next start\n");
      break;
    }
  }
  return all_ok;
}

int run(const Cli& c) {
  const agent::AgentConfig cfg = config_from(c);
  agent::StreamOptions opt;
  opt.paced = !c.flags.count("--fast");
  opt.checksum_kind = *checksum_kind_from(cfg.checksum);  // checked when the config was read
  if (!cfg.protocol.empty()) opt.protocol_minor = *stream::minor_of(cfg.protocol);  // checked likewise
  if (c.has("--timeout")) opt.timeout = std::chrono::seconds(integer_option(c, "--timeout", 1, 86400));
  opt.stop_requested = [] { return g_stop.load(); };

  if (c.command == "forward") {
    if (!c.positional.empty()) throw UsageError("forward takes no positional arguments");
    const agent::SpoolLock lock(cfg.spool_dir);
    const auto ep = open_endpoints(cfg);
    return forward_backlog(*ep, cfg, opt) ? 0 : 1;
  }
  if (c.command == "replay") {
    if (c.positional.size() != 1) throw UsageError("replay needs exactly one RUN_DIR");
    RunRecording run = read_run(c.positional[0]);
    const agent::SpoolLock lock(cfg.spool_dir);
    const auto ep = open_endpoints(cfg);
    forward_backlog(*ep, cfg, opt);
    return stream_one(*ep, std::move(run), cfg, opt) ? 0 : 1;
  }
  // simulate: identification runs every identification_interval_s, the
  // first at start, until `runs` are done (0: until stopped); monitoring
  // snapshots every monitoring_interval_s from their own thread.
  if (!c.positional.empty()) throw UsageError("simulate takes no positional arguments");
  if (cfg.model.empty()) throw UsageError("simulate needs --model PLANT.json (or \"model\" in the config)");
  if (cfg.pump_id.empty()) throw UsageError("simulate needs --pump ID (or \"pump_id\" in the config)");
  agent::SimulationOptions sim;
  sim.pump_id = cfg.pump_id;
  const agent::SimulationConfig& sc = cfg.simulation;
  sim.faults = c.opts.count("--fault") ? c.opts.at("--fault") : sc.faults;
  sim.excitation = sc.excitation;
  sim.sample_rate_hz = sc.sample_rate_hz;
  sim.period_samples = sc.period_samples;
  sim.f_min_hz = sc.f_min_hz;
  sim.f_max_hz = sc.f_max_hz;
  sim.settle_periods = sc.settle_periods;
  sim.meas_periods = sc.meas_periods;
  sim.monitoring_s = sc.monitoring_s;
  sim.seed = c.has("--seed") ? static_cast<uint64_t>(integer_option(c, "--seed", 0, 1ll << 40)) : sc.seed;
  sim.speed_spread_pct = c.has("--speed-spread") ? percent_option(c, "--speed-spread") : sc.speed_spread_pct;
  sim.seal_drift_pct = c.has("--seal-drift") ? percent_option(c, "--seal-drift") : sc.seal_drift_pct;
  sim.seal_drift_link_pct = c.has("--seal-drift-link") ? percent_option(c, "--seal-drift-link") : sc.seal_drift_link_pct;
  const long long runs = c.has("--runs") ? integer_option(c, "--runs", 0, 1000000) : cfg.runs;
  sim.runs = runs;
  for (const auto& f : sim.faults) {
    agent::FaultSchedule spec;
    try {
      spec = agent::parse_fault_schedule(f);
    } catch (const InputError& e) {
      throw UsageError(e.what());
    }
    if (spec.end_value && !spec.to_run && runs == 0)
      throw UsageError("--fault " + f + ": a ramp A..B ends at the last run: give --runs N or @runK..M");
  }
  const PlantModel plant = read_plant_file(cfg.model);
  const agent::SpoolLock lock(cfg.spool_dir);
  agent::PumpSimulator simulator(plant, sim);
  const AmbLoopReport& loop = simulator.loop().report();
  std::fprintf(stderr,
               "ambdiag-agent: simulating pump %s from %s: %s, faults [%s]; AMB loop at %g Hz, k_i %g N/A, k_s %g N/m "
               "(first actuator), spectral radius %.6f\n",
               cfg.pump_id.c_str(), cfg.model.c_str(), sim.excitation.c_str(), join(sim.faults).c_str(),
               simulator.loop().controller_rate_hz(), loop.k_i_n_per_a.at(0), loop.k_s_n_per_m.at(0), loop.spectral_radius);
  const auto endpoints = open_endpoints(cfg);
  stream::AgentEndpoints& ep = *endpoints;
  std::unique_ptr<agent::SnapshotPublisher> snapshots;
  if (cfg.monitoring_interval_s > 0) {
    agent::SimulationOptions mon = sim;
    mon.seed = sim.seed + 1;         // its own noise,
    mon.operating_seed = sim.seed;   // the runs' speed, seal drift and faults
    snapshots = std::make_unique<agent::SnapshotPublisher>(ep, cfg.pump_id, std::make_unique<agent::PumpSimulator>(plant, mon),
                                                           cfg.monitoring_interval_s);
  }
  forward_backlog(ep, cfg, opt);
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  auto seconds = [&] { return std::chrono::duration<double>(clock::now() - t0).count(); };
  agent::Ticker ident(cfg.identification_interval_s, 0.0);
  bool all_ok = true;
  for (long long i = 0; (runs == 0 || i < runs) && !g_stop; ++i) {
    while (!g_stop && !ident.due(seconds())) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (g_stop) break;
    if (snapshots) snapshots->follow_run(i + 1);
    const auto sim_t0 = clock::now();
    RunRecording run_rec = simulator.identification_run();
    const agent::OperatingState& st = simulator.state();
    std::string active;
    for (const auto& f : st.faults)
      if (f.active) active += (active.empty() ? "" : ", ") + f.name + "=" + std::to_string(f.value);
    char loop_note[64] = "loop kept";
    if (simulator.last_rebuild_s() > 0) std::snprintf(loop_note, sizeof loop_note, "loop rebuilt in %.3f s", simulator.last_rebuild_s());
    std::fprintf(stderr,
                 "ambdiag-agent: identification run %lld%s simulated in %.2f s (%s): %.1f rpm, seal drift %+.4f, "
                 "faults in force [%s]\n",
                 i + 1, runs ? (" of " + std::to_string(runs)).c_str() : "",
                 std::chrono::duration<double>(clock::now() - sim_t0).count(), loop_note, st.speed_rpm, st.seal_drift,
                 active.c_str());
    all_ok = stream_one(ep, std::move(run_rec), cfg, opt) && all_ok;
    ident.done(seconds());
  }
  if (snapshots)
    std::fprintf(stderr, "ambdiag-agent: %ld monitoring snapshots published\n", snapshots->published());
  return all_ok && !g_stop ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  ambdiag::retain_freed_memory();
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  if (argc >= 2 && (std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h")) {
    std::printf("%s", kUsage);
    return 0;
  }
  try {
    const Cli c = parse(argc, argv);
    return run(c);
  } catch (const UsageError& e) {
    std::fprintf(stderr, "ambdiag-agent: %s\n%s", e.what(), kUsage);
    return 2;
  } catch (const InputError& e) {
    std::fprintf(stderr, "ambdiag-agent: bad input: %s\n", e.what());
    return 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ambdiag-agent: error: %s\n", e.what());
    return 1;
  }
}
