// `ambdiag explain --model PLANT.json --measured FRF.csv [--json] [--svg FILE]
// [-o IMPROVED.json]`: where and why model and recording differ, and the
// improved model (algorithms/explain.h).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/explain/explain.h"
#include "ambdiag/core/error.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/io_util.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/svg_plot.h"
#include "args.h"
#include "command.h"

namespace ambdiag::cli {

namespace {

using nlohmann::json;

// A plant file, honouring the "acquisition" extension that explain writes.
PlantVariant read_variant(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open");
  std::stringstream ss;
  ss << in.rdbuf();
  json doc;
  try {
    doc = json::parse(ss.str());
  } catch (const json::parse_error& e) {
    throw InputError(path + ": not JSON: " + e.what());
  }
  try {
    return variant_from_json(doc);
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
}

int run_explain(const std::vector<std::string>& argv) {
  const Args args(argv, {"--model", "--svg", "-o", "--max-steps"}, {"--json"}, {"--measured"});
  args.expect_positional(0, "");
  const auto model_path = args.option("--model");
  const std::vector<std::string> meas_paths = args.values("--measured");
  if (!model_path || meas_paths.empty()) throw UsageError("explain needs --model PLANT.json and --measured FRF.csv");
  const std::string* meas_path = &meas_paths.front();
  const PlantVariant given = read_variant(*model_path);
  if (given.delay_s != 0.0) throw InputError(*model_path + ": acquisition.delay_s: explain starts from a plant without a delay");
  const FrfData meas = read_frf_csv(*meas_path);
  // Recordings at other speeds judge the explanation (explain.h).
  std::vector<FrfData> others;
  for (size_t k = 1; k < meas_paths.size(); ++k) others.push_back(read_frf_csv(meas_paths[k]));

  ExplainOptions opt;
  if (auto s = args.number("--max-steps")) {
    if (*s < 0 || *s > 50) throw UsageError("--max-steps: must be 0..50");
    opt.max_steps = static_cast<int>(*s);
  }
  opt.progress = [](const std::string& s) { std::fprintf(stderr, "explain: %s\n", s.c_str()); };
  const auto t0 = std::chrono::steady_clock::now();
  const ExplainResult r = explain(given.plant, meas, others, opt);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::fprintf(stderr, "explain: %.2f s, %d rotor FRF solves, %d evaluations\n", secs, r.rotor_solves, r.evaluations);

  if (auto svg = args.option("--svg")) write_file_atomic(*svg, explain_svg(r, meas));
  if (auto o = args.option("-o")) write_file_atomic(*o, variant_to_json(r.improved).dump(2) + "\n");

  if (args.flag("--json")) {
    std::cout << explain_to_json(r).dump(2) << "\n";
    return kExitOk;
  }
  for (const auto& s : r.story) std::printf("%s\n", s.c_str());
  std::printf("\nmismatches (beyond noise):\n");
  for (const auto& m : r.mismatches) {
    std::string ents;
    for (const auto& e : m.entries) ents += (ents.empty() ? "" : " ") + e;
    std::printf("  %7.1f-%7.1f Hz  %-20s chi2/line %9.3g  %s%s\n", m.band_lo_hz, m.band_hi_hz, m.kind.c_str(), m.chi2_per_line,
                m.mode ? ("near " + (*m.mode)["label"].get<std::string>() + ", ").c_str() : "", ents.c_str());
  }
  std::printf("\n%-14s %-8s %12s %12s %12s\n", "entry", "", "nrmse before", "after", "noise floor");
  for (const auto& e : r.entries)
    std::printf("%-14s %-8s %12.4f %12.4f %12.4f\n", (e.output + "/" + e.input).c_str(), "", e.nrmse_before, e.nrmse_after, e.noise_floor);
  std::printf("\nmodes (model -> improved model):\n");
  for (const auto& m : r.modes) {
    std::printf("  %-28s %-9s %-15s", m.label.c_str(), m.whirl.c_str(), m.status.c_str());
    if (std::isfinite(m.model_f_hz)) std::printf(" %8.2f Hz %5.2f %%", m.model_f_hz, 100 * m.model_zeta);
    else std::printf(" %8s    %5s  ", "-", "-");
    if (std::isfinite(m.improved_f_hz)) std::printf("  -> %8.2f Hz %5.2f %%\n", m.improved_f_hz, 100 * m.improved_zeta);
    else std::printf("  -> %8s\n", "-");
  }
  return kExitOk;
}

}  // namespace

std::vector<Command> explain_commands() {
  return {{{"explain"},
           "where and why the model and the recording differ, and the improved model",
           "usage: ambdiag explain --model PLANT.json --measured FRF.csv [FRF2.csv ...] [--json] [--svg FILE]\n"
           "                       [-o IMPROVED.json] [--max-steps N]\n\n"
           "Compares the model's FRF matrix with the measured one, weighted by the measurement's\n"
           "sigma columns; locates bands beyond noise (entries, modes, kind of difference); corrects\n"
           "existing parameters within bounds first (updated_parameters), then names missing physics\n"
           "(housing_mode, seal_cross_coupling, added_mass, acquisition_delay, sensor_noncollocation,\n"
           "coupling_stiffness, stiffness_change, gyroscopic, damping) chosen by a penalised criterion\n"
           "checked on held-out lines. Prints the improved plant model (improved_model; a delay is the\n"
           "extension \"acquisition\": {\"delay_s\"}), NRMSE before/after per entry, and with --svg the\n"
           "measured, model and improved FRFs with the mismatch bands. Recordings after the first (each\n"
           "stating another speed_rpm) judge the explanation: physics one speed cannot tell apart are\n"
           "decided by how they change with speed, a seal's cross-coupling gets its speed law, and\n"
           "other_speeds shows whether the improved model holds there. See docs/explain.md.\n",
           run_explain}};
}

}  // namespace ambdiag::cli
