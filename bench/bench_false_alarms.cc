// False alarms of detection under operating conditions on the time-domain
// path (issue 16): simulated healthy pumps in closed loop (edge_agent's
// PumpSimulator: each run at its own speed, seal coefficients drifting),
// the FRF estimated from each run as the server does, detection against a
// reference learnt from the pump's first 3 runs. Prints how many of the
// later runs each test flags at alpha 0.05 / 0.01 / 0.001 / 1e-5 and a
// Kolmogorov-Smirnov distance of their p-values from uniform; the
// synthetic-FRF calibration is OperatingReferenceSlow (docs/diagnosis.md).
// Then the fleet false-alarm budget (issue 19): each pump's runs in order
// through the server's alarm engine (server/src/alarms) with the default
// rules and with no on-delay on detection: at each alpha the detection
// alarms raised, and how much a detection depends on the run before (the
// on-delay's gain assumes little); at the server's alpha every default rule
// on the runs' real results (diagnosed when detection fired).
//
// Usage: bench_false_alarms [--pumps P] [--runs N] [--speed-spread PCT] [--seal-drift PCT] [--seed S]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "alarms/alarm_engine.h"
#include "alarms/alarm_state.h"
#include "trends/run_series.h"
#include "ambdiag/algorithms/diagnosis/diagnosis_report.h"
#include "ambdiag/algorithms/diagnosis/operating_reference.h"
#include "ambdiag/algorithms/estimation/frf_estimation.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/process_memory.h"
#include "ambdiag/edge_agent/simulate.h"
#include "bench_util.h"

namespace {

// Largest distance between the empirical CDF of p and the uniform one.
double ks_uniform(std::vector<double> p) {
  std::sort(p.begin(), p.end());
  double d = 0.0;
  const double n = static_cast<double>(p.size());
  for (size_t i = 0; i < p.size(); ++i)
    d = std::max({d, (static_cast<double>(i) + 1) / n - p[i], p[i] - static_cast<double>(i) / n});
  return d;
}

// One healthy run as the server's alarm engine sees it: the analysis
// result's detection (and, when detection fired at the server's alpha, the
// diagnosis, as the server stores them) and its combined p-value.
struct HealthyRun {
  double p = 1.0;
  nlohmann::json result;
};

// The alarms the engine raises on one pump's runs, by rule. At the server's
// alpha (`result` given) the run's real result is evaluated by every
// default rule. At other alphas only detection is: the engine reads the
// ratio statistic / threshold, and from a p-value the bench uses
// ln p / ln alpha, which is >= 1 exactly when p <= alpha and falls as p
// grows (the clear limit 0.8 is then p > alpha^0.8).
std::map<std::string, int> alarms_raised(const ambdiag::server::detail::AlarmRuleSet& rules, const std::vector<HealthyRun>& runs,
                                         std::optional<double> proxy_alpha, double speed_rpm) {
  using namespace ambdiag::server::detail;
  PumpAlarms pump;
  std::map<std::string, int> raises;
  for (size_t r = 0; r < runs.size(); ++r) {
    RunFacts f;
    f.pump_id = "FA";
    f.run_id = "FA/" + std::to_string(r);
    f.time = iso_ms(static_cast<std::int64_t>(r) * 3'600'000'000'000LL);
    f.speed_rpm = f.model_speed_rpm.emplace(speed_rpm);
    f.has_detection = true;
    if (proxy_alpha) {
      f.detected = runs[r].p <= *proxy_alpha;
      f.values = {{"detection.ratio", "1", std::log(std::max(runs[r].p, 1e-300)) / std::log(*proxy_alpha), std::nullopt}};
    } else {
      const nlohmann::json& res = runs[r].result;
      f.detected = res["detection"]["detected"].get<bool>();
      f.values = run_series(res);
      if (res["diagnosis"].is_object() && !res["diagnosis"]["faults"].empty())
        f.best_fault = res["diagnosis"]["faults"][0]["fault"].get<std::string>();
    }
    const auto changes = evaluate_run(rules, pump, f);
    for (const auto& [i, e] : changes.events)
      if (e.kind == "raise") ++raises[changes.alarms[i].rule];
  }
  return raises;
}

int total(const std::map<std::string, int>& m) {
  int n = 0;
  for (const auto& [rule, k] : m) n += k;
  return n;
}

std::string by_rule(const std::map<std::string, int>& m) {
  std::string s;
  for (const auto& [rule, k] : m) s += (s.empty() ? " (" : ", ") + rule + " " + std::to_string(k);
  return s.empty() ? s : s + ")";
}

}  // namespace

int main(int argc, char** argv) {
  ambdiag::retain_freed_memory();
  int pumps = 4, runs = 25;
  double speed_spread = 3.0, seal_drift = 2.0;
  unsigned seed = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--pumps" && i + 1 < argc) pumps = std::atoi(argv[++i]);
    else if (a == "--runs" && i + 1 < argc) runs = std::atoi(argv[++i]);
    else if (a == "--speed-spread" && i + 1 < argc) speed_spread = std::atof(argv[++i]);
    else if (a == "--seal-drift" && i + 1 < argc) seal_drift = std::atof(argv[++i]);
    else if (a == "--seed" && i + 1 < argc) seed = static_cast<unsigned>(std::atoi(argv[++i]));
    else {
      std::fprintf(stderr, "usage: bench_false_alarms [--pumps P] [--runs N] [--speed-spread PCT] [--seal-drift PCT] [--seed S]\n");
      return 2;
    }
  }
  const std::string plant = std::string(AMBDIAG_BENCH_SHARED_DATA) + "/reference_pump/plant.json";
  std::vector<double> p_residual, p_drift, p_combined;
  std::vector<std::vector<HealthyRun>> by_pump(static_cast<size_t>(std::max(0, pumps)));
  const ambdiag::PlantModel plant_model = ambdiag::read_plant_file(plant);
  const double t0 = ambdiag::bench::wall_seconds(), c0 = ambdiag::bench::cpu_seconds();
  for (int k = 0; k < pumps; ++k) {
    ambdiag::agent::SimulationOptions o;
    o.pump_id = "FA-" + std::to_string(k);
    o.speed_spread_pct = speed_spread;
    o.seal_drift_pct = seal_drift;
    o.seed = seed * 1000 + static_cast<unsigned>(k);
    ambdiag::agent::PumpSimulator sim(plant, o);
    std::vector<ambdiag::FrfData> refs;
    for (int r = 0; r < 3; ++r) refs.push_back(ambdiag::estimate_frf(sim.identification_run()).frf);
    const ambdiag::OperatingReference ref = ambdiag::learn_operating_reference(sim.plant(), refs);
    for (int r = 3; r < runs; ++r) {
      const ambdiag::FrfData frf = ambdiag::estimate_frf(sim.identification_run()).frf;
      ambdiag::DiagnosisOptions opt;
      opt.detect_only = true;
      opt.alpha = ambdiag::kRecommendedAlphaPerRun;
      const ambdiag::DiagnosisResult d = ambdiag::diagnose(sim.plant(), ref, frf, opt);
      p_residual.push_back(d.operating.residual_p_value);
      p_drift.push_back(d.operating.drift_p_value);
      p_combined.push_back(d.p_value);
      // What the server keeps of the run (run_analysis.cc): the detection,
      // and the diagnosis when it fired.
      HealthyRun run{d.p_value, {{"speed_rpm", d.operating.speed_rpm},
                                 {"detection", {{"detected", d.detected}, {"ratio", d.threshold > 0 ? d.statistic / d.threshold : 0.0},
                                                {"p_value", d.p_value}}},
                                 {"diagnosis", nullptr}}};
      if (d.detected) {
        opt.detect_only = false;
        run.result["diagnosis"] = ambdiag::diagnosis_to_json(ambdiag::diagnose(sim.plant(), ref, frf, opt), plant_model);
        std::fprintf(stderr, "pump %d run %d: detected; diagnosis %s\n", k, r + 1,
                     run.result["diagnosis"]["faults"].empty() ? "-" : run.result["diagnosis"]["faults"][0].dump().c_str());
      }
      by_pump[static_cast<size_t>(k)].push_back(std::move(run));
      std::fprintf(stderr, "pump %d run %d: %.0f rpm, residual p %.3g, drift p %.3g\n", k, r + 1, d.operating.speed_rpm,
                   d.operating.residual_p_value, d.operating.drift_p_value);
    }
  }
  const double n = static_cast<double>(p_combined.size());
  std::printf("%d pumps x %d runs after 3 reference runs each: %zu healthy runs (speed +-%.1f %%, seal drift %.1f %%), "
              "%.0f s wall, %.0f CPU-s\n",
              pumps, runs - 3, p_combined.size(), speed_spread, seal_drift, ambdiag::bench::wall_seconds() - t0,
              ambdiag::bench::cpu_seconds() - c0);
  for (const auto& [name, p] : {std::pair{"residual", &p_residual}, {"drift", &p_drift}, {"combined", &p_combined}}) {
    std::printf("%-9s", name);
    for (double alpha : {0.05, 0.01, 0.001, 1e-5}) {
      const auto hits = std::count_if(p->begin(), p->end(), [&](double v) { return v < alpha; });
      std::printf("  p < %-6g: %3ld (expected %.2f)", alpha, static_cast<long>(hits), alpha * n);
    }
    std::printf("  KS D %.3f (5 %% point %.3f)\n", ks_uniform(*p), 1.36 / std::sqrt(n));
  }
  using ambdiag::server::detail::merge_rule_sets;
  using ambdiag::server::detail::default_rule_set_json;
  const auto defaults = merge_rule_sets(default_rule_set_json(), nlohmann::json::object(), "defaults");
  const auto no_delay = merge_rule_sets(default_rule_set_json(),
                                        {{"rules", {{{"id", "detection"}, {"on_delay", {{"k", 1}, {"n", 1}}}}}}}, "no on-delay");
  const double speed = plant_model.speed_rpm;
  const int on_k = defaults.find("detection")->on_k, on_n = defaults.find("detection")->on_n;
  std::printf("alarms raised over %.0f healthy runs (the server's alarm engine, docs/diagnosis.md section 8):\n", n);
  for (double alpha : {0.05, 0.01, 0.001}) {
    int plain = 0, delayed = 0, pairs = 0, both = 0, firsts = 0;
    for (const auto& runs_of : by_pump) {
      plain += total(alarms_raised(no_delay, runs_of, alpha, speed));
      delayed += total(alarms_raised(defaults, runs_of, alpha, speed));
      for (size_t r = 1; r < runs_of.size(); ++r) {
        ++pairs;
        firsts += runs_of[r - 1].p <= alpha ? 1 : 0;
        both += runs_of[r - 1].p <= alpha && runs_of[r].p <= alpha ? 1 : 0;
      }
    }
    std::printf("  detection at alpha %-6g: 1 of 1: %3d alarms (%.2g per run); default %d of %d: %3d (%.2g per run); "
                "detected after a detected run: %d of %d\n",
                alpha, plain, plain / n, on_k, on_n, delayed, delayed / n, both, firsts);
  }
  std::map<std::string, int> plain, delayed;
  for (const auto& runs_of : by_pump) {
    for (const auto& [rule, k] : alarms_raised(no_delay, runs_of, std::nullopt, speed)) plain[rule] += k;
    for (const auto& [rule, k] : alarms_raised(defaults, runs_of, std::nullopt, speed)) delayed[rule] += k;
  }
  std::printf("  every default rule at the server's alpha %g: detection 1 of 1: %d alarms%s; default (%d of %d): %d%s\n",
              ambdiag::kRecommendedAlphaPerRun, total(plain), by_rule(plain).c_str(), on_k, on_n, total(delayed), by_rule(delayed).c_str());
  return 0;
}
