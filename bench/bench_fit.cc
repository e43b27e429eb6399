// Identification benchmarks (docs/benchmarks.md, "Identification"): the
// rational fit with automatic order of the reference pump's 5 x 5 FRF at
// 1000 lines (a file with constant sigma per entry, and the FRF estimated
// from its run, sigma per line and entry), of ident_7mode (SISO, 2000 lines), and of the real amrotor rig
// (FRF estimated from its chirp run, 8 accelerances); the FRF estimation of
// that run too.
//
//   bench_fit --benchmark_repetitions=3
//
// Counters: modes (physical modes reported), pairs (pole pairs of the model).
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <string>

#include "ambdiag/algorithms/estimation/frf_estimation.h"
#include "ambdiag/algorithms/identification/rational_fit.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/process_memory.h"
#include "ambdiag/core/run_recording.h"

namespace {

std::string shared(const std::string& rel) {
  const char* env = std::getenv("AMBDIAG_SHARED_DATA");
  return std::string(env ? env : AMBDIAG_BENCH_SHARED_DATA) + "/" + rel;
}

const ambdiag::RunRecording& amrotor_run() {
  static const ambdiag::RunRecording r = ambdiag::read_run(shared("external/amrotor_mlps_sweep"));
  return r;
}

void fit(benchmark::State& state, const ambdiag::FrfData& frf) {
  ambdiag::RationalFitResult r;
  for (auto _ : state) {
    r = ambdiag::fit_rational(frf);
    benchmark::DoNotOptimize(r);
  }
  state.counters["modes"] = static_cast<double>(r.modes.size());
  state.counters["pairs"] = r.model.pair_count();
}

void BM_FitPump5x5AutoOrder(benchmark::State& state) {
  static const ambdiag::FrfData f = ambdiag::read_frf_csv(shared("reference_pump/frf_ref_1.csv"));
  fit(state, f);
}
BENCHMARK(BM_FitPump5x5AutoOrder)->Unit(benchmark::kMillisecond);

// The ordinary use: the pump's FRF estimated from its multisine run (sigma
// per line and entry, not separable: the general path), estimated once in
// the set-up with the library call.
void BM_FitPumpEstimatedFromRunAutoOrder(benchmark::State& state) {
  static const ambdiag::FrfData f = ambdiag::estimate_frf(ambdiag::read_run(shared("reference_pump/run_ref_1"))).frf;
  fit(state, f);
}
BENCHMARK(BM_FitPumpEstimatedFromRunAutoOrder)->Unit(benchmark::kMillisecond);

void BM_FitSevenModeAutoOrder(benchmark::State& state) {
  static const ambdiag::FrfData f = ambdiag::read_frf_csv(shared("ident_7mode/frf.csv"));
  fit(state, f);
}
BENCHMARK(BM_FitSevenModeAutoOrder)->Unit(benchmark::kMillisecond);

void BM_FrfAmrotorGated(benchmark::State& state) {
  const ambdiag::RunRecording& run = amrotor_run();
  for (auto _ : state) benchmark::DoNotOptimize(ambdiag::estimate_frf(run));
}
BENCHMARK(BM_FrfAmrotorGated)->Unit(benchmark::kMillisecond);

void BM_FitAmrotorAutoOrder(benchmark::State& state) {
  static const ambdiag::FrfData f = ambdiag::estimate_frf(amrotor_run()).frf;
  fit(state, f);
}
BENCHMARK(BM_FitAmrotorAutoOrder)->Unit(benchmark::kMillisecond);

}  // namespace

// BENCHMARK_MAIN with the memory setting of the ambdiag executables.
int main(int argc, char** argv) {
  ambdiag::retain_freed_memory();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
