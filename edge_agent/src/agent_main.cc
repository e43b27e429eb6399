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
#include <map>
#include <string>
#include <vector>

#include "ambdiag/core/error.h"
#include "ambdiag/core/run_recording.h"
#include "ambdiag/edge_agent/block_source.h"
#include "ambdiag/edge_agent/config.h"
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
    "       ambdiag-agent simulate --model PLANT.json --pump ID [--fault NAME ...] [--domain D] [options]\n"
    "\n"
    "Streams runs over Cyclone DDS to `ambdiag serve`; exits 0 once every sample is\n"
    "acknowledged as committed and the server verified the run's count and checksum.\n"
    "\n"
    "options:\n"
    "  --config FILE        agent configuration (JSON; see edge_agent/README.md)\n"
    "  --fast               replay as fast as possible (default: paced at the sample rate)\n"
    "  --domain D           DDS domain id (default 0 or the config's)\n"
    "  --partition NAME     DDS partition, one per site (default \"site\")\n"
    "  --pump ID            pump id (default: the recording's)\n"
    "  --spool-dir DIR      store-and-forward folder (default ./ambdiag-spool)\n"
    "  --spool-limit BYTES  bound on the spool's disk use (default 1 GiB)\n"
    "  --block-frames N     frames per sample block (default 512)\n"
    "  --timeout S          give up after S seconds without progress (default 60)\n"
    "  --runs N             simulate: number of identification runs (default 1)\n"
    "  --duration S         simulate: seconds per run (default 8)\n"
    "  --seed N             simulate: noise seed (default 1)\n"
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
                                                    "--fault", "--runs", "--duration", "--seed"};
  Cli c;
  if (argc < 2) throw UsageError("missing command (replay or simulate)");
  c.command = argv[1];
  if (c.command != "replay" && c.command != "simulate") throw UsageError("unknown command '" + c.command + "'");
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--fast") {
      c.flags[a] = true;
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

agent::AgentConfig config_from(const Cli& c) {
  agent::AgentConfig cfg = c.has("--config") ? agent::load_agent_config(c.opt("--config")) : agent::AgentConfig{};
  if (c.has("--domain")) cfg.domain = static_cast<int>(integer_option(c, "--domain", 0, 232));
  if (c.has("--partition")) cfg.partition = c.opt("--partition");
  if (c.has("--pump")) cfg.pump_id = c.opt("--pump");
  if (c.has("--spool-dir")) cfg.spool_dir = c.opt("--spool-dir");
  if (c.has("--spool-limit")) cfg.spool_limit_bytes = static_cast<uint64_t>(integer_option(c, "--spool-limit", 0, 1ll << 50));
  if (c.has("--block-frames")) cfg.block_frames = static_cast<uint32_t>(integer_option(c, "--block-frames", 1, 65536));
  if (c.has("--model")) cfg.model = c.opt("--model");
  validate(cfg, "command line");
  return cfg;
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
               "ambdiag-agent: run %s: %s: %s (%lld blocks, %lld frames, checksum %016llx, %lld sent, %lld resends, "
               "spool peak %llu bytes)\n",
               run_id.c_str(), r.complete ? "committed" : "NOT committed", r.message.c_str(),
               static_cast<long long>(r.n_blocks), static_cast<long long>(r.total_frames),
               static_cast<unsigned long long>(r.checksum), static_cast<long long>(r.blocks_sent),
               static_cast<long long>(r.resends), static_cast<unsigned long long>(r.max_spool_disk_bytes));
  return r.complete;
}

int run(const Cli& c) {
  const agent::AgentConfig cfg = config_from(c);
  agent::StreamOptions opt;
  opt.paced = !c.flags.count("--fast");
  if (c.has("--timeout")) opt.timeout = std::chrono::seconds(integer_option(c, "--timeout", 1, 86400));
  opt.stop_requested = [] { return g_stop.load(); };

  if (c.command == "replay") {
    if (c.positional.size() != 1) throw UsageError("replay needs exactly one RUN_DIR");
    RunRecording run = read_run(c.positional[0]);
    stream::AgentEndpoints ep(cfg.domain, cfg.partition);
    return stream_one(ep, std::move(run), cfg, opt) ? 0 : 1;
  }
  throw UsageError("simulate is not built yet");
}

}  // namespace

int main(int argc, char** argv) {
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
