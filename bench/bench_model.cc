// Plant model benchmarks (docs/benchmarks.md, "Plant model"): modal
// analysis and the 5 x 5 FRF matrix at 1000 lines for the reference pump and
// for generated shafts of 100 to 2000 elements, with the fitted exponent of
// time against element count.
//
//   bench_model --benchmark_repetitions=5 [--benchmark_filter=...]
//
// Counters: assembly_ms (rotor incl. free-free modes), setup_ms
// (factorization, eigen-decomposition or Krylov basis), lines_ms (the per-line
// work), poles, krylov (basis size).
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/algorithms/model/modal_analysis.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/process_memory.h"
#include "generated_rotor.h"

namespace {

using ambdiag::FrfMethod;
using ambdiag::FrfReport;
using ambdiag::FrfSynthesisOptions;
using ambdiag::ModalBasis;
using ambdiag::PlantModel;

const PlantModel& pump() {
  static const PlantModel p = [] {
    const char* env = std::getenv("AMBDIAG_SHARED_DATA");
    const std::string dir = env ? env : AMBDIAG_BENCH_SHARED_DATA;
    return ambdiag::read_plant_file(dir + "/reference_pump/plant.json");
  }();
  return p;
}

const std::vector<double>& lines_1000() {
  static const std::vector<double> f = ambdiag::frequency_grid(1.0, 1000.0, 1.0);
  return f;
}

FrfSynthesisOptions options_for(int method) {
  FrfSynthesisOptions o;
  if (method == 0) return o;
  o.method = FrfMethod::modal;
  o.modal_basis = method == 1 ? ModalBasis::all : ModalBasis::krylov;
  return o;
}

void report_counters(benchmark::State& state, const FrfReport& r) {
  state.counters["assembly_ms"] = 1e3 * r.assembly_s;
  state.counters["setup_ms"] = 1e3 * r.setup_s;
  state.counters["lines_ms"] = 1e3 * r.lines_s;
  state.counters["poles"] = r.poles;
  state.counters["krylov"] = r.krylov_size;
  state.SetLabel(r.method);
}

void BM_PumpModalAnalysis(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(ambdiag::modal_analysis(pump(), 2950.0));
}
BENCHMARK(BM_PumpModalAnalysis)->Unit(benchmark::kMillisecond);

// Arg: 0 direct, 1 modal with all eigenvalues, 2 modal with a Krylov basis.
void BM_PumpFrf(benchmark::State& state) {
  const FrfSynthesisOptions o = options_for(static_cast<int>(state.range(0)));
  FrfReport r;
  for (auto _ : state) benchmark::DoNotOptimize(ambdiag::synthesize_frf(pump(), 2950.0, lines_1000(), o, &r));
  report_counters(state, r);
}
BENCHMARK(BM_PumpFrf)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

const PlantModel& shaft(int elements) {
  static std::map<int, PlantModel> cache;
  auto it = cache.find(elements);
  if (it == cache.end()) it = cache.emplace(elements, ambdiag::testing::generated_rotor(elements)).first;
  return it->second;
}

void BM_ShaftModal(benchmark::State& state) {
  ambdiag::ModalOptions o;
  o.f_max_hz = 1000.0;
  const PlantModel& p = shaft(static_cast<int>(state.range(0)));
  ambdiag::ModalResult r;
  for (auto _ : state) benchmark::DoNotOptimize(r = ambdiag::modal_analysis(p, 3000.0, o));
  state.counters["krylov"] = r.krylov_size;
  state.SetLabel(r.solver);
}

void BM_ShaftFrfDirect(benchmark::State& state) {
  const PlantModel& p = shaft(static_cast<int>(state.range(0)));
  FrfReport r;
  for (auto _ : state) benchmark::DoNotOptimize(ambdiag::synthesize_frf(p, 3000.0, lines_1000(), options_for(0), &r));
  report_counters(state, r);
}

void BM_ShaftFrfKrylov(benchmark::State& state) {
  const PlantModel& p = shaft(static_cast<int>(state.range(0)));
  FrfReport r;
  for (auto _ : state) benchmark::DoNotOptimize(ambdiag::synthesize_frf(p, 3000.0, lines_1000(), options_for(2), &r));
  report_counters(state, r);
}

void shaft_sizes(benchmark::internal::Benchmark* b) {
  for (int n : {100, 250, 500, 1000, 2000}) b->Arg(n);
  b->Unit(benchmark::kMillisecond);
}
BENCHMARK(BM_ShaftModal)->Apply(shaft_sizes);
BENCHMARK(BM_ShaftFrfKrylov)->Apply(shaft_sizes);
BENCHMARK(BM_ShaftFrfDirect)->Apply(shaft_sizes)->Iterations(1);

// Console output plus the times of each shaft family, for the fitted
// exponent t ~ elements^p (least squares on log-log; medians when the runs
// are repeated).
class ScalingReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& r : runs) {
      const std::string& fn = r.run_name.function_name;
      if (fn.rfind("BM_Shaft", 0) != 0 || r.error_occurred) continue;
      const bool median = r.run_type == Run::RT_Aggregate && r.aggregate_name == "median";
      if (r.run_type == Run::RT_Aggregate && !median) continue;
      if (r.repetitions > 1 && !median) continue;
      const double elements = std::atof(r.run_name.args.c_str());
      times_[fn].push_back({elements, r.GetAdjustedRealTime(), r.GetAdjustedCPUTime()});
    }
    ConsoleReporter::ReportRuns(runs);
  }

  void PrintScaling() const {
    for (const auto& [name, pts] : times_) {
      if (pts.size() < 2) continue;
      std::printf("%-20s scaling exponent: real %.2f, cpu %.2f (%zu sizes)\n", name.c_str(), slope(pts, true),
                  slope(pts, false), pts.size());
    }
  }

 private:
  struct Point {
    double elements, real, cpu;
  };
  static double slope(const std::vector<Point>& pts, bool real) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    const double n = static_cast<double>(pts.size());
    for (const Point& p : pts) {
      const double x = std::log(p.elements), y = std::log(real ? p.real : p.cpu);
      sx += x;
      sy += y;
      sxx += x * x;
      sxy += x * y;
    }
    return (n * sxy - sx * sy) / (n * sxx - sx * sx);
  }
  std::map<std::string, std::vector<Point>> times_;
};

}  // namespace

int main(int argc, char** argv) {
  ambdiag::retain_freed_memory();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  ScalingReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  reporter.PrintScaling();
  benchmark::Shutdown();
  return 0;
}
