// The reference pump's 5 x 5 FRF at 1000 lines (1-1000 Hz), timed by wall
// clock and by process CPU time (the machine is shared: CPU time is the
// figure that does not depend on the others' load), median over
// repetitions, with the phases of the synthesis report and the load average.
//
//   bench_pump_frf [--reps N] [--basis automatic|all|krylov|direct] [--loops K] [--tol T]
//
// Each repetition runs the synthesis K times (default 20) and reports the
// mean per call, so that a repetition lasts long enough for the clocks; the
// first call of the process is timed apart.
#include <time.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/process_memory.h"
#include "bench_util.h"

namespace {

using ambdiag::bench::median;

double clock_s(clockid_t id) {
  timespec ts{};
  clock_gettime(id, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

std::string load_average() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  in >> a >> b >> c;
  return a + " " + b + " " + c;
}

}  // namespace

int main(int argc, char** argv) {
  ambdiag::retain_freed_memory();
  int reps = 7, loops = 20;
  std::string basis = "automatic";
  double tol = ambdiag::FrfSynthesisOptions{}.krylov_tol;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--reps") reps = std::max(1, std::atoi(argv[i + 1]));
    else if (flag == "--loops") loops = std::max(1, std::atoi(argv[i + 1]));
    else if (flag == "--basis") basis = argv[i + 1];
    else if (flag == "--tol") tol = std::atof(argv[i + 1]);
    else {
      std::fprintf(stderr, "unknown option %s\n", flag.c_str());
      return 2;
    }
  }
  const char* env = std::getenv("AMBDIAG_SHARED_DATA");
  const std::string dir = env ? env : AMBDIAG_BENCH_SHARED_DATA;
  const ambdiag::PlantModel plant = ambdiag::read_plant_file(dir + "/reference_pump/plant.json");
  const std::vector<double> f = ambdiag::frequency_grid(1.0, 1000.0, 1.0);
  ambdiag::FrfSynthesisOptions o;
  o.krylov_tol = tol;
  if (basis != "direct") {
    o.method = ambdiag::FrfMethod::modal;
    if (basis == "all") o.modal_basis = ambdiag::ModalBasis::all;
    else if (basis == "krylov") o.modal_basis = ambdiag::ModalBasis::krylov;
    else if (basis != "automatic") {
      std::fprintf(stderr, "--basis: automatic, all, krylov or direct\n");
      return 2;
    }
  }
  std::printf("load average before: %s\n", load_average().c_str());
  {
    // The first call of a fresh process: what one `ambdiag model frf`
    // pays (every page of the working set faulted in once).
    const double w0 = clock_s(CLOCK_MONOTONIC);
    const ambdiag::FrfData h = ambdiag::synthesize_frf(plant, 2950.0, f, o);
    std::printf("first call of the process: wall %.3f ms\n", 1e3 * (clock_s(CLOCK_MONOTONIC) - w0));
    if (h.entries.size() != 25) return 1;
  }
  std::vector<double> wall, cpu, assembly, setup, lines;
  ambdiag::FrfReport rep;
  for (int r = 0; r < reps; ++r) {
    const double w0 = clock_s(CLOCK_MONOTONIC), c0 = clock_s(CLOCK_PROCESS_CPUTIME_ID);
    double a = 0, s = 0, l = 0;
    for (int k = 0; k < loops; ++k) {
      const ambdiag::FrfData h = ambdiag::synthesize_frf(plant, 2950.0, f, o, &rep);
      if (h.entries.size() != 25) return 1;
      a += rep.assembly_s;
      s += rep.setup_s;
      l += rep.lines_s;
    }
    wall.push_back((clock_s(CLOCK_MONOTONIC) - w0) / loops);
    cpu.push_back((clock_s(CLOCK_PROCESS_CPUTIME_ID) - c0) / loops);
    assembly.push_back(a / loops);
    setup.push_back(s / loops);
    lines.push_back(l / loops);
  }
  std::printf("method: %s; poles %d (in band %d), krylov %d, residual %.2e\n", rep.method.c_str(), rep.poles,
              rep.poles_in_band, rep.krylov_size, rep.krylov_residual);
  std::printf("median of %d x %d calls: wall %.3f ms, CPU %.3f ms (assembly %.3f, setup %.3f, lines %.3f ms wall)\n",
              reps, loops, 1e3 * median(wall), 1e3 * median(cpu), 1e3 * median(assembly), 1e3 * median(setup),
              1e3 * median(lines));
  std::printf("load average after: %s\n", load_average().c_str());
  return 0;
}
