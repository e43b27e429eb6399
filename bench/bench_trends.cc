// Trend queries (docs/benchmarks.md "Trends"): a historian filled directly
// through the storage API as the analysis service fills it (one analysis job
// per run, its series kept by finish_job), then GET .../trends over real
// HTTP: a year of hourly runs (8760 points) and 100 000 points, each with
// max_points=1000 (min/max buckets), one client and then 10 at once.
//
//   bench_trends [--dir DIR] [--keep] [--requests N]
// --keep: reuse DIR's database when it holds the pumps (the fill takes a while).
#include <httplib.h>

#include <atomic>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <random>
#include <thread>

#include <nlohmann/json.hpp>

#include "ambdiag/server/rest_server.h"
#include "ambdiag/storage/historian.h"
#include "bench_util.h"

namespace {

namespace fs = std::filesystem;
using ambdiag::storage::Historian;

constexpr std::int64_t kHourNs = 3'600'000'000'000;
constexpr const char* kMode = "mode.radial bending 1 (forward).f_hz";

std::string run_json(const std::string& run_id, const std::string& pump_id, std::int64_t t_ns) {
  return nlohmann::json{{"format", "ambdiag.run/1"}, {"pump_id", pump_id}, {"run_id", run_id},
                        {"kind", "monitoring"}, {"started_at", ambdiag::storage::utc_from_ns(t_ns)},
                        {"speed_rpm", 3000.0}, {"sample_rate_hz", 1000.0},
                        {"channels", {{{"name", "x"}, {"role", "displacement"}, {"unit", "m"}}}}}
      .dump();
}

// `n` hourly runs of the pump, each analysed: the series an analysis with a
// reference and a diagnosis gives (ratio, nrmse, two modes with sd, a fault).
void fill(Historian& h, const std::string& pump_id, int n) {
  const std::int64_t t0 = ambdiag::storage::ns_from_utc("2020-01-01T00:00:00Z", "t0");
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (int first = 0; first < n; first += 1000) {
    auto batch = h.write_batch();
    for (int i = first; i < std::min(n, first + 1000); ++i) {
      const std::string run_id = pump_id + "/r" + std::to_string(i);
      h.begin_run(ambdiag::storage::run_header_from_json(run_json(run_id, pump_id, t0 + i * kHourNs)));
      const auto [id, created] = h.enqueue_job({"analysis", pump_id, run_id, 1, 1});
      const auto job = h.claim_job("bench");
      const double spike = i % 997 == 0 ? 5.0 : 0.0;
      h.finish_job(id, job->attempts, "{}", {},
                   std::vector<ambdiag::storage::SeriesValue>{
                       {"detection.ratio", "1", 0.4 + 0.1 * noise(rng) + spike, std::nullopt},
                       {"fit.nrmse", "1", 0.02 + 0.001 * noise(rng), std::nullopt},
                       {kMode, "Hz", 52.0 + 0.05 * noise(rng), 0.05},
                       {"mode.radial bending 1 (forward).zeta", "1", 0.02 + 0.001 * noise(rng), 0.001},
                       {"fault.impeller_seal_wear.clearance_factor", "1", 1.0 + 1e-5 * i + 0.02 * noise(rng), 0.02}});
    }
    batch.commit();
  }
}

double percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[std::min(v.size() - 1, static_cast<size_t>(p * static_cast<double>(v.size())))];
}

// Latencies (ms) of `requests` GETs from each of `clients` keep-alive clients at once.
std::vector<double> latencies(int port, const std::string& url, int clients, int requests, std::size_t& reply_bytes) {
  std::vector<double> all;
  std::mutex mu;
  std::atomic<int> failures{0};
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c)
    threads.emplace_back([&] {
      httplib::Client http("127.0.0.1", port);
      http.set_keep_alive(true);
      std::vector<double> mine;
      for (int k = 0; k < requests; ++k) {
        const double t = ambdiag::bench::wall_seconds();
        const auto r = http.Get(url);
        mine.push_back(1e3 * (ambdiag::bench::wall_seconds() - t));
        if (!r || r->status != 200) {
          ++failures;
        } else {
          std::lock_guard l(mu);
          reply_bytes = r->body.size();
        }
      }
      std::lock_guard l(mu);
      all.insert(all.end(), mine.begin(), mine.end());
    });
  for (auto& t : threads) t.join();
  if (failures > 0) std::fprintf(stderr, "bench_trends: %d requests failed\n", failures.load());
  return all;
}

}  // namespace

int main(int argc, char** argv) {
  fs::path dir = fs::temp_directory_path() / "ambdiag-bench-trends";
  bool keep = false;
  int requests = 50;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--dir") == 0 && i + 1 < argc) dir = argv[++i];
    else if (std::strcmp(argv[i], "--keep") == 0) keep = true;
    else if (std::strcmp(argv[i], "--requests") == 0 && i + 1 < argc) requests = std::atoi(argv[++i]);
  }
  const std::string db = (dir / "h.db").string();
  const std::vector<std::pair<std::string, int>> pumps = {{"P-YEAR", 8760}, {"P-100K", 100000}};
  {
    if (!keep) fs::remove_all(dir);
    fs::create_directories(dir);
    auto h = Historian::open(db);
    for (const auto& [pump, n] : pumps) {
      const auto p = h.find_pump(pump);
      if (p && p->n_runs == n) continue;
      const double t = ambdiag::bench::wall_seconds(), cpu = ambdiag::bench::cpu_seconds();
      fill(h, pump, n);
      std::printf("filled %s: %d analysed runs in %.1f s (%.1f CPU-s)\n", pump.c_str(), n,
                  ambdiag::bench::wall_seconds() - t, ambdiag::bench::cpu_seconds() - cpu);
    }
  }
  ambdiag::server::RestOptions opt;
  opt.db_path = db;
  opt.host = "127.0.0.1";
  opt.anonymous_read = true;
  ambdiag::server::RestServer server(opt);
  const int port = server.start();
  std::printf("%-58s %8s %8s %8s %10s\n", "GET .../trends?series=...&max_points=1000", "median", "p95", "max", "reply");
  for (const auto& [pump, n] : pumps)
    for (int clients : {1, 10}) {
      const std::string url = "/api/v1/pumps/" + pump + "/trends?series=" + ambdiag::server::url_encode_segment(kMode) +
                              "&max_points=1000";
      std::size_t bytes = 0;
      latencies(port, url, 1, 3, bytes);  // warm the page cache and the connections
      const double cpu = ambdiag::bench::cpu_seconds();
      const auto ms = latencies(port, url, clients, requests, bytes);
      char what[96];
      std::snprintf(what, sizeof what, "%s, %d points, %d client%s", pump.c_str(), n, clients, clients > 1 ? "s" : "");
      std::printf("%-58s %6.1f ms %6.1f ms %6.1f ms %7.0f kB   %.1f ms CPU per request\n", what,
                  ambdiag::bench::median(ms), percentile(ms, 0.95), percentile(ms, 1.0), 1e-3 * static_cast<double>(bytes),
                  1e3 * (ambdiag::bench::cpu_seconds() - cpu) / static_cast<double>(ms.size()));
    }
  server.stop();
  if (!keep) fs::remove_all(dir);
  return 0;
}
