// Explain benchmark (docs/benchmarks.md, "Explain (issue 7)"): one explain
// run per shared explain_* case, wall and CPU time (user + sys; the machine
// is shared), rotor FRF solves and model evaluations.
//
//   bench_explain [-v] [CASE ...]   (default: the four explain_* cases;
//                                    -v: progress, explanations and updates on stderr)
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "ambdiag/algorithms/explain/explain.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/process_memory.h"
#include "bench_util.h"

using ambdiag::bench::cpu_seconds;

int main(int argc, char** argv) {
  ambdiag::retain_freed_memory();
  const char* env = std::getenv("AMBDIAG_SHARED_DATA");
  const std::string dir = env ? env : AMBDIAG_BENCH_SHARED_DATA;
  std::vector<std::string> cases(argv + 1, argv + argc);
  const bool verbose = !cases.empty() && cases.front() == "-v";
  if (verbose) cases.erase(cases.begin());
  if (cases.empty()) cases = {"explain_cross_coupling", "explain_delay", "explain_paper_table3", "explain_none"};
  std::printf("%-24s %8s %8s %8s %8s %6s %6s %9s %9s\n", "case", "wall_s", "cpu_s", "solves", "evals", "expl", "upd", "nrmse0",
              "nrmse1");
  for (const auto& c : cases) {
    const ambdiag::PlantModel p = ambdiag::read_plant_file(dir + "/" + c + "/nominal.json");
    const ambdiag::FrfData m = ambdiag::read_frf_csv(dir + "/" + c + "/frf.csv");
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = cpu_seconds();
    ambdiag::ExplainOptions opt;
    if (verbose)
      opt.progress = [c0](const std::string& s) { std::fprintf(stderr, "  [cpu %6.2f s] %s\n", cpu_seconds() - c0, s.c_str()); };
    const ambdiag::ExplainResult r = ambdiag::explain(p, m, opt);
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double cpu = cpu_seconds() - c0;
    std::printf("%-24s %8.2f %8.2f %8d %8d %6zu %6zu %9.4f %9.4f\n", c.c_str(), wall, cpu, r.rotor_solves, r.evaluations,
                r.explanations.size(), r.updated_parameters.size(), r.nrmse_before, r.nrmse_after);
    if (verbose) {
      for (const auto& e : r.explanations)
        std::fprintf(stderr, "  explained: %s %s %s sd %s\n", e.physics.c_str(), e.location.dump().c_str(), e.parameters.dump().c_str(),
                     e.sd.dump().c_str());
      for (const auto& u : r.updated_parameters) std::fprintf(stderr, "  updated: %s %.6g -> %.6g\n", u.path.c_str(), u.from, u.to);
      for (const auto& u : r.unexplained) std::fprintf(stderr, "  unexplained: %.1f-%.1f Hz %s\n", u.band_lo_hz, u.band_hi_hz, u.kind.c_str());
    }
  }
  return 0;
}
