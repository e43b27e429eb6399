// Alarm evaluation of one run (issue 19, target < 5 ms): the engine alone
// (evaluate_run on the run's values, all default rules), and the whole
// evaluation the server makes after an analysis (AlarmEvaluator::catch_up:
// read the cursor, the job's result and the pump's alarms, evaluate, write
// alarms, journal and cursor in one transaction) on a historian file.
// The result is shaped like a real one (12 labelled modes, detection with
// two seal links, on every 10th run a diagnosis naming a worn piston with
// 18 ranked faults).
//
// Usage: bench_alarms [--runs N] [--db FILE]
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "alarms/alarm_engine.h"
#include "alarms/alarm_evaluator.h"
#include "ambdiag/core/checksum.h"
#include "ambdiag/core/io_util.h"
#include "ambdiag/storage/historian.h"
#include "ambdiag/storage/monitoring.h"
#include "bench_util.h"

namespace {

using nlohmann::json;
using namespace ambdiag::server::detail;

json result_of(int i) {
  json modes = json::array();
  for (int m = 0; m < 12; ++m)
    modes.push_back({{"label", "radial bending " + std::to_string(m / 2 + 1) + (m % 2 ? " (backward)" : " (forward)")},
                     {"f_hz", 100.0 + 50.0 * m + 0.1 * (i % 7)}, {"zeta", 0.02 + 0.001 * (i % 3)}, {"f_sd_hz", 0.1},
                     {"zeta_sd", 0.002}, {"model_f_hz", 100.0 + 50.0 * m}, {"model_zeta", 0.02}, {"direction", "x"},
                     {"whirl", "forward"}, {"peak_snr", 40.0}, {"stable_orders", 5}, {"outputs", {1.0, 0.5}}, {"inputs", {1.0, 0.4}}});
  const bool worn = i % 10 == 9;
  json r = {{"speed_rpm", 2950.0 + (i % 5)}, {"nrmse", 0.02}, {"modes", modes},
            {"detection", {{"detected", worn}, {"statistic", worn ? 300.0 : 20.0}, {"threshold", 75.0}, {"ratio", worn ? 4.0 : 0.27},
                           {"false_alarm_rate", 1e-5}, {"dof", 40}, {"p_value", worn ? 1e-12 : 0.4},
                           {"operating", {{"nuisance", {{{"link", "piston"}, {"factor", 1.01}, {"sd", 0.01}},
                                                        {{"link", "seal"}, {"factor", 0.99}, {"sd", 0.01}}}}}}}},
            {"diagnosis", nullptr}};
  if (worn) {
    json faults = json::array();
    for (int f = 0; f < 18; ++f)
      faults.push_back({{"fault", f == 0 ? "balance_piston_wear" : "rotor_crack"}, {"score", f == 0 ? 1.0 : 0.0}, {"bic", 5e4 + f},
                        {"parameters", {{"clearance_factor", 1.45}, {"clearance_factor_sd", 0.02}, {"clearance_factor_ci95", {1.41, 1.49}}}}});
    r["diagnosis"] = {{"faults", faults}};
  }
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 300;
  std::string db = (std::filesystem::temp_directory_path() / "bench_alarms.db").string();
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--runs" && i + 1 < argc) runs = std::atoi(argv[++i]);
    else if (a == "--db" && i + 1 < argc) db = argv[++i];
    else {
      std::fprintf(stderr, "usage: bench_alarms [--runs N] [--db FILE]\n");
      return 2;
    }
  }
  for (const char* ext : {"", "-wal", "-shm"}) std::filesystem::remove(db + ext);
  auto h = ambdiag::storage::Historian::open(db);
  const std::string pump = "B-1";
  h.put_model(pump, R"({"speed_rpm": 2950})", "bench");
  const json defaults = merged_rule_set_json(default_rule_set_json(), json::object(), "defaults");
  const AlarmRuleSet rules = rule_set_from_json(defaults, "defaults");

  // The engine alone.
  std::vector<double> engine_ms;
  PumpAlarms state;
  for (int i = 0; i < runs; ++i) {
    const json r = result_of(i);
    const double t0 = ambdiag::bench::wall_seconds();
    RunFacts f;
    f.pump_id = pump;
    f.run_id = pump + "/" + std::to_string(i);
    f.time = iso_ms(now_ns());
    f.speed_rpm = 2950.0;
    f.model_speed_rpm = 2950.0;
    f.has_detection = true;
    f.detected = r["detection"]["detected"].get<bool>();
    f.values = run_series(r);
    if (f.detected) f.best_fault = "balance_piston_wear";
    for (const auto& s : f.values)
      if (s.name.starts_with("mode.")) f.reference[s.name] = {s.value, 0.05, 3};
    evaluate_run(rules, state, f);
    engine_ms.push_back(1e3 * (ambdiag::bench::wall_seconds() - t0));
  }

  // On the historian, as the server does after each analysis.
  AlarmEvaluator ev(defaults, nullptr);
  std::vector<double> store_ms;
  const std::vector<std::uint8_t> bytes(8 * 300, 0);
  const double c0 = ambdiag::bench::cpu_seconds();
  for (int i = 0; i < runs; ++i) {
    const std::string id = pump + "/" + std::to_string(i);
    json header = {{"format", "ambdiag.run/1"}, {"pump_id", pump}, {"run_id", id}, {"kind", "identification"},
                   {"started_at", ambdiag::storage::utc_from_ns(1'790'000'000'000'000'000LL + i * 3'600'000'000'000LL)},
                   {"speed_rpm", 2950.0}, {"sample_rate_hz", 1000.0},
                   {"channels", {{{"name", "x"}, {"role", "displacement"}, {"unit", "m"}}, {{"name", "f"}, {"role", "excitation"}, {"unit", "N"}}}},
                   {"excitation", {{"type", "multisine"}, {"period_samples", 100}, {"f_min_hz", 1.0}, {"f_max_hz", 400.0},
                                   {"segments", {{{"start", 0}, {"periods", 3}, {"settle_periods", 1}, {"pattern", 0}}}}}}};
    h.begin_run(ambdiag::storage::run_header_from_json(header.dump()));
    const ambdiag::storage::Chunk chunk{0, 0, 300, bytes};
    h.put_chunks(id, std::span(&chunk, 1));
    h.end_run(id, 300, ambdiag::fnv1a64(bytes.data(), bytes.size()));
    h.enqueue_job({"analysis", pump, id, 1, 0});
    const auto job = h.claim_job("bench");
    h.finish_job(job->job_id, job->attempts, result_of(i).dump());
    const double t0 = ambdiag::bench::wall_seconds();
    if (ev.catch_up(h, pump) != 1) std::fprintf(stderr, "run %d not evaluated\n", i);
    store_ms.push_back(1e3 * (ambdiag::bench::wall_seconds() - t0));
  }
  const double cpu = ambdiag::bench::cpu_seconds() - c0;
  auto p95 = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[static_cast<size_t>(0.95 * static_cast<double>(v.size() - 1))];
  };
  std::printf("%d runs (12 labelled modes each, every 10th diagnosed): engine alone median %.3f ms, p95 %.3f ms; "
              "with the historian (read, evaluate, write in one transaction) median %.3f ms, p95 %.3f ms "
              "(%.2f CPU-s for storing and evaluating all); journal entries %lld\n",
              runs, ambdiag::bench::median(engine_ms), p95(engine_ms), ambdiag::bench::median(store_ms), p95(store_ms), cpu,
              static_cast<long long>(h.last_alarm_seq()));
  return 0;
}
