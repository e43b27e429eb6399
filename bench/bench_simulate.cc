// Closed-loop pump simulation speed (docs/benchmarks.md, "Simulated pump"):
// set-up (assembly, matrix exponential, stability check) and simulated
// seconds per CPU second (user + sys; the machine is shared) for the
// reference pump at recorded sample rates of 2048 Hz (controller 8192 Hz,
// as run_ref_1) and 8192 Hz (as run_stepsine).
//
//   bench_simulate [PLANT.json]
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "ambdiag/algorithms/simulation/amb_loop.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/process_memory.h"
#include "bench_util.h"

using ambdiag::bench::cpu_seconds;
using ambdiag::bench::wall_seconds;

int main(int argc, char** argv) {
  ambdiag::retain_freed_memory();
  const char* env = std::getenv("AMBDIAG_SHARED_DATA");
  const std::string path = argc > 1 ? argv[1] : std::string(env ? env : AMBDIAG_BENCH_SHARED_DATA) + "/reference_pump/plant.json";
  const ambdiag::PlantModel plant = ambdiag::read_plant_file(path);
  std::printf("%-10s %-12s %7s %10s %10s %9s %9s %14s %14s\n", "record_hz", "controller_hz", "states", "setup_wall",
              "setup_cpu", "sim_s", "cpu_s", "sim_s/cpu_s", "sim_s/wall_s");
  for (const double fs : {2048.0, 8192.0}) {
    ambdiag::AmbLoopOptions o;
    o.decimation = fs < 8000 ? 4 : 1;
    o.controller_rate_hz = fs * o.decimation;
    double c0 = cpu_seconds(), w0 = wall_seconds();
    ambdiag::AmbLoop loop(plant, o);
    const double setup_cpu = cpu_seconds() - c0, setup_wall = wall_seconds() - w0;
    const double sim_s = 20.0;
    Eigen::MatrixXd r, f, x;
    c0 = cpu_seconds(), w0 = wall_seconds();
    loop.run(static_cast<int64_t>(sim_s * fs), [](int64_t k, std::span<double> out) {
      for (size_t j = 0; j < out.size(); ++j) out[j] = 10.0 * std::sin(1e-3 * static_cast<double>(k) * static_cast<double>(j + 1));
    }, r, f, x);
    const double cpu = cpu_seconds() - c0, wall = wall_seconds() - w0;
    std::printf("%-10.0f %-12.0f %7d %10.2f %10.2f %9.1f %9.2f %14.1f %14.1f\n", fs, o.controller_rate_hz,
                loop.report().states, setup_wall, setup_cpu, sim_s, cpu, sim_s / cpu, sim_s / wall);
  }
  return 0;
}
