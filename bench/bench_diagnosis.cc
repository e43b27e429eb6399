// Diagnosis benchmark (docs/benchmarks.md, "Diagnosis (issue 6)"): one full
// diagnosis (detection, every fault hypothesis of the pump fitted, ranked)
// on each shared fault case, and detection alone on a healthy run.
// Reference statistics are built once per repetition as the CLI does.
//
//   bench_diagnosis [repetitions]     (default 3)
//
// Prints per case the median wall time and CPU time (user + sys of this
// process) over the repetitions, and the model FRF evaluations.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "ambdiag/algorithms/diagnosis/diagnosis.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/process_memory.h"
#include "bench_util.h"

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  ambdiag::retain_freed_memory();
  const int reps = argc > 1 ? std::max(1, std::atoi(argv[1])) : 3;
  const char* env = std::getenv("AMBDIAG_SHARED_DATA");
  const std::string dir = env ? env : AMBDIAG_BENCH_SHARED_DATA;
  const ambdiag::PlantModel plant = ambdiag::read_plant_file(dir + "/reference_pump/plant.json");
  std::vector<ambdiag::FrfData> refs;
  for (int i = 1; i <= 5; ++i) refs.push_back(ambdiag::read_frf_csv(dir + "/reference_pump/frf_ref_" + std::to_string(i) + ".csv"));
  const std::vector<std::string> cases = {"fault_dry_run", "fault_balance_piston_wear", "fault_crack", "reference_pump/frf_ref_1"};
  std::printf("%-28s %10s %10s %8s  %s\n", "case", "wall_s", "cpu_s", "evals", "first");
  for (const auto& c : cases) {
    const std::string path = c.find("frf_ref") != std::string::npos ? dir + "/" + c + ".csv" : dir + "/" + c + "/frf.csv";
    const ambdiag::FrfData meas = ambdiag::read_frf_csv(path);
    std::vector<double> wall, cpu;
    ambdiag::DiagnosisResult r;
    for (int k = 0; k < reps; ++k) {
      const double w0 = ambdiag::bench::wall_seconds(), c0 = ambdiag::bench::cpu_seconds();
      const ambdiag::ReferenceStatistics ref = ambdiag::reference_statistics(refs);
      r = ambdiag::diagnose(plant, ref, meas);
      wall.push_back(ambdiag::bench::wall_seconds() - w0);
      cpu.push_back(ambdiag::bench::cpu_seconds() - c0);
    }
    std::printf("%-28s %10.3f %10.3f %8d  %s\n", c.c_str(), median(wall), median(cpu), r.evaluations,
                r.faults.empty() ? "(not detected)" : r.faults.front().name.c_str());
  }
  return 0;
}
