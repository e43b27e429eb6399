// Streaming benchmark (docs/benchmarks.md, "Streaming (issue 5)"), in one run:
//  1. end to end: K `ambdiag-agent replay --fast` processes into one
//     `ambdiag serve` (real processes, loopback DDS); bytes of samples per
//     second (a) from the first block the server receives to its last commit
//     (every run verified), (b) from the agents' process start (adds process
//     start-up, reading the recordings and DDS discovery);
//  2. the DDS ceiling: Cyclone's `ddsperf` pub -> sub, same payload size;
//  3. the storage ceilings: Historian::put_chunks of the same chunks in
//     batches of 256, one transaction each (no DDS): the bare batched
//     insert (SQLite's own checkpoints in the committing connection; the
//     issue's ceiling) and the server's storage path (checkpoints in a
//     background thread, as `serve` runs it);
//  4. pumps one server carries at 8 kHz x 15 channels float32 (480 kB/s each):
//     P paced agents streaming live at once, each must finish in real time;
//  5. memory with a slow disk: server peak RSS while each commit is delayed.
// 1 and 3 alternate --reps times (the machine is shared: medians, and the
// ratio of each pair measured back to back).
// Usage: bench_stream [--quick] [--seconds S] [--agents K] [--pumps P] [--reps R]
//                     [--inline-checkpoints] [--durability checkpoint|full] (serve's options)
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <random>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "ambdiag/core/checksum.h"
#include "ambdiag/core/process_memory.h"
#include "ambdiag/core/run_recording.h"
#include "ambdiag/storage/historian.h"
#include "bench_util.h"
#include "process.h"

namespace {

namespace fs = std::filesystem;
using ambdiag::testing::Process;
using Clock = std::chrono::steady_clock;
using ambdiag::bench::median;
using namespace std::chrono_literals;

constexpr uint32_t kBlockFrames = 512;
constexpr int kChannels = 15;
constexpr double kRateHz = 8000.0;

double secs(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

// Peak resident memory of a running process (VmHWM), MB.
double peak_rss_mb(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return 0;
}

// An 8 kHz x 15-channel monitoring run of `seconds`, seeded noise.
ambdiag::RunRecording make_run(const std::string& pump, double seconds, unsigned seed) {
  ambdiag::RunRecording r;
  r.pump_id = pump;
  r.run_id = pump + "/bench-" + std::to_string(seed);
  r.kind = "monitoring";
  r.started_at = "2026-11-22T00:00:00Z";
  r.speed_rpm = 2950;
  r.sample_rate_hz = kRateHz;
  for (int c = 0; c < kChannels; ++c) {
    ambdiag::Channel ch;
    ch.name = "x" + std::to_string(c);
    ch.role = ambdiag::ChannelRole::displacement;
    ch.role_text = "displacement";
    ch.unit = "m";
    r.channels.push_back(ch);
  }
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0.0f, 1e-5f);
  r.samples.resize(static_cast<size_t>(seconds * kRateHz) * kChannels);
  for (auto& v : r.samples) v = n(rng);
  return r;
}

struct Env {
  fs::path dir;
  int domain;
  std::map<std::string, std::string> env;
  int n = 0;
  // With DDS Security (--security): the plant PKI made by the deploy
  // script; the server and each agent run with their own identity, the
  // agents publish in their pump's partition only (docs/streaming.md).
  std::optional<fs::path> pki;
  std::map<std::string, std::string> env_of(const std::string& identity) const {
    if (!pki) return env;
    return {{"CYCLONEDDS_URI", env.at("CYCLONEDDS_URI") + ",file://" + (*pki / identity / "security.xml").string()}};
  }
  // Enrols the agents of these pumps (run folders named by pump, see main).
  void enrol(const std::string& pump) const {
    if (!pki) return;
    const std::string cmd = std::string(AMBDIAG_PKI_SCRIPT) + " agent " + pki->string() + " " + pump +
                            " --site bench >>" + (dir / "pki.log").string() + " 2>&1";
    if (std::system(cmd.c_str()) != 0) throw std::runtime_error("enrolling " + pump + " failed: see " + (dir / "pki.log").string());
  }
  std::unique_ptr<Process> server(const std::vector<std::string>& extra = {}) {
    std::vector<std::string> a = {AMBDIAG_CLI, "serve", "--db", (dir / "bench.db").string(), "--http-port", "0",
                                  "--domain", std::to_string(domain), "--quiet"};
    a.insert(a.end(), extra.begin(), extra.end());
    return std::make_unique<Process>(a, env_of("server"), (dir / ("server" + std::to_string(n++) + ".log")).string());
  }
  std::unique_ptr<Process> agent(const fs::path& run, bool fast) {
    std::vector<std::string> a = {AMBDIAG_AGENT, "replay", run.string(), "--domain", std::to_string(domain),
                                  "--spool-dir", (dir / ("spool" + std::to_string(n))).string(), "--timeout", "60"};
    if (fast) a.push_back("--fast");
    const std::string pump = run.filename().string();
    if (pki) a.insert(a.end(), {"--config", (*pki / "agents" / pump / "agent.json").string()});
    return std::make_unique<Process>(a, env_of("agents/" + pump), (dir / ("agent" + std::to_string(n++) + ".log")).string());
  }
};

// CPU seconds (user + sys) a running process used so far (/proc/PID/stat).
double process_cpu_s(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/stat");
  std::string stat((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  std::istringstream in(stat.substr(stat.rfind(')') + 2));  // fields from 3 (state) on
  std::string field;
  double ticks = 0;
  for (int i = 3; i <= 15 && in >> field; ++i)
    if (i == 14 || i == 15) ticks += std::stod(field);  // utime, stime
  return ticks / static_cast<double>(sysconf(_SC_CLK_TCK));
}

// UDP datagrams the kernel dropped for want of socket receive buffer, all
// sockets of this network namespace (/proc/net/snmp, Udp RcvbufErrors): a
// reliable DDS reader recovers them by retransmission, which costs time.
long long udp_rcvbuf_errors() {
  std::ifstream f("/proc/net/snmp");
  std::string names, values, line;
  while (std::getline(f, line))
    if (line.rfind("Udp: ", 0) == 0) names.empty() ? names = line : values = line;
  std::istringstream n(names), v(values);
  std::string name, value;
  while (n >> name && v >> value)
    if (name == "RcvbufErrors") return std::stoll(value);
  return -1;
}

// CPU-seconds the whole machine spent busy (every process, every core) so
// far (/proc/stat, first line: all but idle and iowait). The machine is
// shared: busy minus our processes' CPU is what the others took meanwhile.
double machine_busy_s() {
  std::ifstream f("/proc/stat");
  std::string cpu;
  double v[8] = {};
  f >> cpu;
  for (double& x : v) f >> x;
  return (v[0] + v[1] + v[2] + v[5] + v[6] + v[7]) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

struct E2e {
  double machine_busy_s = 0, machine_s = 0;  // all cores, during the case; cores x wall
  long long udp_drops = 0;
  double mb_per_s = 0, wall_s = 0, cpu_s = 0, server_rss_mb = 0, server_cpu_s = 0;
  double span_s = 0, span_mb_per_s = 0;  // first block received -> last commit (server's figure)
  std::string queue_peak;                 // "N bytes", from the server's last line
  long long resends = 0, orphans = 0, duplicates = 0, dds_rejected = 0;  // agents' re-sends; server: blocks before the header, twice
  int failed = 0;
};

// The server's last line: "... committed; S s from the first block received to the last commit; ..."
double span_from_log(const std::string& log) {
  const std::regex re(R"(committed; ([0-9.]+) s from the first block)");
  std::smatch m;
  return std::regex_search(log, m, re) ? std::stod(m[1]) : 0.0;
}

// K agents replay their runs into one server as fast as possible.
E2e end_to_end(Env& e, const std::vector<fs::path>& runs, double bytes, bool fast,
               const std::vector<std::string>& server_extra = {}) {
  fs::remove(e.dir / "bench.db");
  fs::remove(e.dir / "bench.db-wal");
  fs::remove(e.dir / "bench.db-shm");
  auto server = e.server(server_extra);
  std::this_thread::sleep_for(1s);  // server up and discovered
  const double cpu0 = ambdiag::bench::cpu_seconds(RUSAGE_CHILDREN);
  const long long drops0 = udp_rcvbuf_errors();
  const double busy0 = machine_busy_s();
  const auto t0 = Clock::now();
  std::vector<std::unique_ptr<Process>> agents;
  for (const auto& r : runs) agents.push_back(e.agent(r, fast));
  E2e out;
  double rss = 0;
  for (auto& a : agents) {
    int rc;
    while ((rc = a->wait(200ms)) == -1000) rss = std::max(rss, peak_rss_mb(server->pid()));
    if (rc != 0) {
      ++out.failed;
      std::fprintf(stderr, "agent failed (%d):\n%s\n", rc, a->log().c_str());
    }
  }
  out.wall_s = secs(Clock::now() - t0);
  out.udp_drops = udp_rcvbuf_errors() - drops0;
  out.machine_busy_s = machine_busy_s() - busy0;
  out.machine_s = out.wall_s * static_cast<double>(sysconf(_SC_NPROCESSORS_ONLN));
  out.server_rss_mb = std::max(rss, peak_rss_mb(server->pid()));
  out.server_cpu_s = process_cpu_s(server->pid());
  server->signal(SIGTERM);
  server->wait(30s);
  out.cpu_s = ambdiag::bench::cpu_seconds(RUSAGE_CHILDREN) - cpu0;
  out.mb_per_s = bytes / out.wall_s / 1e6;
  out.span_s = span_from_log(server->log());
  {
    const std::regex re(R"(queue peak ([0-9]+ bytes))");
    std::smatch m;
    const std::string log = server->log();
    if (std::regex_search(log, m, re)) out.queue_peak = m[1];
    const std::regex counts(R"(([0-9]+) duplicates, ([0-9]+) before their run's header, ([0-9]+) refused)");
    if (std::regex_search(log, m, counts))
      out.duplicates = std::stoll(m[1]), out.orphans = std::stoll(m[2]), out.dds_rejected = std::stoll(m[3]);
  }
  for (auto& a : agents) {
    const std::regex re(R"(([0-9]+) resends)");
    std::smatch m;
    const std::string log = a->log();
    if (std::regex_search(log, m, re)) out.resends += std::stoll(m[1]);
  }
  out.span_mb_per_s = out.span_s > 0 ? bytes / out.span_s / 1e6 : 0;
  return out;
}

// ddsperf pub -> sub for `seconds` with payload `size`; MB/s of the sub.
double ddsperf(Env& e, size_t size, int seconds) {
  auto sub = std::make_unique<Process>(
      std::vector<std::string>{"/usr/bin/ddsperf", "-i", std::to_string(e.domain + 1), "-D", std::to_string(seconds + 2), "sub"},
      e.env, (e.dir / "ddsperf_sub.log").string());
  std::this_thread::sleep_for(500ms);
  auto pub = std::make_unique<Process>(
      std::vector<std::string>{"/usr/bin/ddsperf", "-i", std::to_string(e.domain + 1), "-D", std::to_string(seconds), "pub",
                               "size", std::to_string(size)},
      e.env, (e.dir / "ddsperf_pub.log").string());
  pub->wait(std::chrono::seconds(seconds + 10));
  sub->wait(std::chrono::seconds(seconds + 10));
  // Lines like "... size 30720 total 123 lost 0 delta 45 rate 32.10 kS/s 7890.12 Mb/s (...)"
  const std::regex re(R"(([0-9.]+) Mb/s)");
  std::vector<double> rates;
  std::istringstream in(sub->log());
  std::string line;
  while (std::getline(in, line)) {
    std::smatch m;
    if (std::regex_search(line, m, re)) rates.push_back(std::stod(m[1]));
  }
  if (rates.size() > 2) rates = std::vector<double>(rates.begin() + 1, rates.end() - 1);  // drop ramp-up/down
  double sum = 0;
  for (double r : rates) sum += r;
  return rates.empty() ? 0 : sum / static_cast<double>(rates.size()) / 8.0;  // Mbit/s -> MB/s
}

// Historian::put_chunks of the runs' chunks, 256 per transaction; with
// `background_checkpoints` configured as `ambdiag serve` runs it.
double storage_ceiling(const fs::path& dir, const std::vector<ambdiag::RunRecording>& runs,
                       bool background_checkpoints, double* cpu_s) {
  const fs::path db = dir / "ceiling.db";
  for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(db.string() + suffix);
  auto h = ambdiag::storage::Historian::open(db.string());
  if (background_checkpoints) h.checkpoint_in_background();
  double bytes = 0;
  const double cpu0 = ambdiag::bench::cpu_seconds();
  const auto t0 = Clock::now();
  for (const auto& run : runs) {
    h.begin_run(ambdiag::storage::run_header_from_json(ambdiag::run_to_json(run).dump()));
    const auto* p = reinterpret_cast<const uint8_t*>(run.samples.data());
    const int64_t frames = run.frame_count();
    std::vector<ambdiag::storage::Chunk> batch;
    int64_t seq = 0;
    for (int64_t f = 0; f < frames; f += kBlockFrames) {
      const int64_t nf = std::min<int64_t>(kBlockFrames, frames - f);
      batch.push_back({seq++, f, nf, {p + f * kChannels * 4, static_cast<size_t>(nf * kChannels * 4)}});
      bytes += static_cast<double>(nf * kChannels * 4);
      if (batch.size() == 256 || f + nf >= frames) {
        h.put_chunks(run.run_id, batch);
        batch.clear();
      }
    }
  }
  const double wall = secs(Clock::now() - t0);
  *cpu_s = ambdiag::bench::cpu_seconds() - cpu0;
  return bytes / wall / 1e6;
}

}  // namespace

int main(int argc, char** argv) {
  ambdiag::retain_freed_memory();
  double seconds = 30;  // per run: 30 s x 8 kHz x 15 ch x 4 B = 14.4 MB
  int agents = 4, pumps = 16, reps = 3, failed_total = 0;
  bool quick = false, security = false;
  std::vector<std::string> serve_extra;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") quick = true;
    else if (a == "--seconds" && i + 1 < argc) seconds = std::atof(argv[++i]);
    else if (a == "--agents" && i + 1 < argc) agents = std::atoi(argv[++i]);
    else if (a == "--pumps" && i + 1 < argc) pumps = std::atoi(argv[++i]);
    else if (a == "--reps" && i + 1 < argc) reps = std::max(1, std::atoi(argv[++i]));
    else if (a == "--inline-checkpoints") serve_extra.push_back("--bench-inline-checkpoints");
    else if (a == "--durability" && i + 1 < argc) serve_extra.insert(serve_extra.end(), {"--durability", argv[++i]});
    else if (a == "--security") security = true;
    else {
      std::fprintf(stderr, "usage: bench_stream [--quick] [--seconds S] [--agents K] [--pumps P] [--reps R] [--inline-checkpoints]\n"
                           "                    [--durability checkpoint|full] [--security]\n");
      return 2;
    }
  }
  if (quick) seconds = 5, agents = 2, pumps = 4, reps = 1;
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // progress line by line, also into a file

  Env e;
  e.dir = fs::temp_directory_path() / ("ambdiag_bench_stream_" + std::to_string(getpid()));
  fs::create_directories(e.dir);
  e.domain = 180 + static_cast<int>(getpid() % 40);
  e.env = {{"CYCLONEDDS_URI", "file://" AMBDIAG_CYCLONE_LOCAL_XML}};
  if (security) {
    e.pki = e.dir / "pki";
    const std::string cmd = std::string(AMBDIAG_PKI_SCRIPT) + " init " + e.pki->string() + " >>" +
                            (e.dir / "pki.log").string() + " 2>&1";
    if (std::system(cmd.c_str()) != 0) {
      std::fprintf(stderr, "the PKI script failed: see %s\n", (e.dir / "pki.log").c_str());
      return 1;
    }
    std::printf("DDS Security on: authentication, access control and encryption (deploy/security/ambdiag-pki.sh)\n");
  }

  std::vector<ambdiag::RunRecording> runs;
  std::vector<fs::path> run_dirs;
  double bytes = 0;
  for (int k = 0; k < agents; ++k) {
    runs.push_back(make_run("B-" + std::to_string(k), seconds, static_cast<unsigned>(k + 1)));
    run_dirs.push_back(e.dir / runs.back().pump_id);  // named by pump: the agent's identity (--security)
    e.enrol(runs.back().pump_id);
    ambdiag::write_run(run_dirs.back().string(), runs.back());
    bytes += static_cast<double>(runs.back().samples.size() * 4);
  }
  std::printf("runs: %d x %.0f s at 8 kHz x 15 ch float32 = %.1f MB total, blocks of %u frames (%u B)\n", agents,
              seconds, bytes / 1e6, kBlockFrames, kBlockFrames * kChannels * 4);

  // Two storage ceilings: the bare batched insert the issue names (SQLite's
  // own WAL checkpoints in the committing connection, as STACK.md measured
  // it), and the server's own storage path (checkpoints in a background
  // thread, docs/storage.md), which uses the second core for the copy into
  // the database file and so runs faster than the bare insert.
  std::vector<double> e2e_span, e2e_wall, e2e_cpu, ceil_rate, ceil_cpu, ratio, bare_rate, bare_ratio;
  E2e fast;
  for (int rep = 0; rep < reps; ++rep) {
    fast = end_to_end(e, run_dirs, bytes, true, serve_extra);
    std::printf("rep %d: end to end (%d agents --fast -> serve -> committed, verified): %.1f MB/s from the first "
                "block received to the last commit (%.2f s); %.1f MB/s from the agents' start (%.2f s wall); "
                "CPU %.2f s (user+sys, all processes; server %.2f s); server peak RSS %.0f MB; UDP datagrams dropped by "
                "the kernel %lld; machine busy %.2f of %.2f CPU-s (others %.2f); agents' re-sends %lld, blocks before "
                "their header %lld, duplicates %lld, refused by the full DDS reader %lld; failed %d\n",
                rep, agents, fast.span_mb_per_s, fast.span_s, fast.mb_per_s, fast.wall_s, fast.cpu_s,
                fast.server_cpu_s, fast.server_rss_mb, fast.udp_drops, fast.machine_busy_s, fast.machine_s,
                std::max(0.0, fast.machine_busy_s - fast.cpu_s), fast.resends, fast.orphans, fast.duplicates,
                fast.dds_rejected, fast.failed);
    double bare_cpu = 0, st_cpu = 0;
    const double bare = storage_ceiling(e.dir, runs, false, &bare_cpu);
    const double st = storage_ceiling(e.dir, runs, true, &st_cpu);
    std::printf("rep %d: ceiling Historian::put_chunks, 256 chunks per transaction, background checkpoints as in "
                "serve: %.1f MB/s (%.2f s wall, CPU %.2f s); end to end / ceiling %.0f %%; the same with SQLite's own "
                "checkpoints in the committing thread: %.1f MB/s (CPU %.2f s), end to end / that %.0f %%\n",
                rep, st, bytes / st / 1e6, st_cpu, 100.0 * fast.span_mb_per_s / st, bare, bare_cpu,
                100.0 * fast.span_mb_per_s / bare);
    e2e_span.push_back(fast.span_mb_per_s);
    e2e_wall.push_back(fast.mb_per_s);
    e2e_cpu.push_back(fast.cpu_s);
    ceil_rate.push_back(st);
    ceil_cpu.push_back(st_cpu);
    ratio.push_back(fast.span_mb_per_s / st);
    bare_rate.push_back(bare);
    bare_ratio.push_back(fast.span_mb_per_s / bare);
    if (fast.failed) failed_total += fast.failed;
  }

  const double dds = ddsperf(e, kBlockFrames * kChannels * 4, quick ? 4 : 8);
  std::printf("ceiling ddsperf pub->sub, size %u: %.1f MB/s\n", kBlockFrames * kChannels * 4, dds);
  std::printf("median of %d: end to end %.1f MB/s (first block -> last commit), %.1f MB/s (from agent start), "
              "CPU %.2f s; bare batched insert %.1f MB/s; server storage path (background checkpoints) %.1f MB/s, "
              "CPU %.2f s\n",
              reps, median(e2e_span), median(e2e_wall), median(e2e_cpu), median(bare_rate), median(ceil_rate),
              median(ceil_cpu));
  const double lower = std::min(dds, median(bare_rate));
  std::printf("end to end / lower ceiling (%s): %.0f %% of the medians; median of the back-to-back pairs %.0f %%\n",
              dds < median(bare_rate) ? "ddsperf" : "bare batched insert", 100.0 * median(e2e_span) / lower,
              100.0 * median(bare_ratio));
  std::printf("end to end / the server's own storage path alone: %.0f %% of the medians; median of the pairs %.0f %%\n",
              100.0 * median(e2e_span) / median(ceil_rate), 100.0 * median(ratio));
  std::printf("pumps at 8 kHz x 15 ch (0.48 MB/s each) by end-to-end throughput: %.0f\n", median(e2e_span) / 0.48);

  // Live pumps: P paced agents at once must finish in about real time.
  {
    std::vector<fs::path> live;
    double live_bytes = 0;
    const double live_s = quick ? 3 : 10;
    for (int k = 0; k < pumps; ++k) {
      const auto r = make_run("L-" + std::to_string(k), live_s, static_cast<unsigned>(100 + k));
      live.push_back(e.dir / r.pump_id);
      e.enrol(r.pump_id);
      ambdiag::write_run(live.back().string(), r);
      live_bytes += static_cast<double>(r.samples.size() * 4);
    }
    const E2e paced = end_to_end(e, live, live_bytes, false);
    failed_total += paced.failed;
    std::printf("live: %d pumps paced at 8 kHz x 15 ch for %.0f s: all committed after %.2f s wall (real time %.0f s), "
                "CPU %.2f s (agents + server; server alone %.2f s = %.1f ms per pump-second), server peak RSS %.0f "
                "MB, failed %d\n",
                pumps, live_s, paced.wall_s, live_s, paced.cpu_s, paced.server_cpu_s,
                1000.0 * paced.server_cpu_s / (pumps * live_s), paced.server_rss_mb, paced.failed);
  }

  // Slow disk: every historian commit delayed 50 ms; memory must stay bounded.
  {
    const E2e slow = end_to_end(e, run_dirs, bytes, true, {"--bench-commit-delay-ms", "50"});
    failed_total += slow.failed;
    std::printf("slow disk (+50 ms per commit): %.1f MB/s, server peak RSS %.0f MB (fast disk: %.0f MB), queue peak "
                "%s, failed %d\n",
                slow.span_mb_per_s, slow.server_rss_mb, fast.server_rss_mb, slow.queue_peak.c_str(), slow.failed);
  }
  fs::remove_all(e.dir);
  std::printf("loss: %s\n", failed_total == 0 ? "none (every run verified complete: count and checksum)"
                                               : "RUNS FAILED, see above");
  return failed_total == 0 ? 0 : 1;
}
