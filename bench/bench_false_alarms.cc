// False alarms of detection under operating conditions on the time-domain
// path (issue 16): simulated healthy pumps in closed loop (edge_agent's
// PumpSimulator: each run at its own speed, seal coefficients drifting),
// the FRF estimated from each run as the server does, detection against a
// reference learnt from the pump's first 3 runs. Prints how many of the
// later runs each test flags at alpha 0.05 / 0.01 / 0.001 / 1e-5 and a
// Kolmogorov-Smirnov distance of their p-values from uniform; the
// synthetic-FRF calibration is OperatingReferenceSlow (docs/diagnosis.md).
//
// Usage: bench_false_alarms [--pumps P] [--runs N] [--speed-spread PCT] [--seal-drift PCT] [--seed S]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "ambdiag/algorithms/diagnosis/operating_reference.h"
#include "ambdiag/algorithms/estimation/frf_estimation.h"
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
  return 0;
}
