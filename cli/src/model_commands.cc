// `ambdiag model modes|frf`: the plant model's modes and FRF matrix.
#include <algorithm>
#include <cstdio>
#include <limits>
#include <iostream>

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/model/campbell.h"
#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/algorithms/model/modal_analysis.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/io_util.h"
#include "ambdiag/core/plant_model.h"
#include "args.h"
#include "command.h"

namespace ambdiag::cli {

namespace {

using nlohmann::json;

double speed_of(const Args& args, const PlantModel& plant) {
  const double rpm = args.number("--speed").value_or(plant.speed_rpm);
  if (rpm < 0) throw UsageError("--speed: must be >= 0");
  return rpm;
}

json mode_json(const Mode& m, bool shapes) {
  json j = {{"f_hz", m.f_hz},        {"zeta", m.zeta},     {"direction", m.direction},
            {"whirl", to_string(m.whirl)}, {"kind", m.kind},     {"log_decrement", m.log_decrement()},
            {"eigenvalue", {m.eigenvalue.real(), m.eigenvalue.imag()}}};
  if (m.overdamped) j["overdamped"] = true;
  if (!m.label.empty()) j["label"] = m.label;
  if (m.kind == "rotor") j["fwd_fraction"] = m.fwd_fraction;
  if (m.zeta >= 1.0) j["log_decrement"] = nullptr;
  if (shapes && m.shape.size() > 0) {
    json s = json::array();
    for (Eigen::Index i = 0; i < m.shape.size(); i += 4) {
      s.push_back({{"x", {m.shape(i).real(), m.shape(i).imag()}}, {"y", {m.shape(i + 1).real(), m.shape(i + 1).imag()}}});
    }
    j["shape"] = s;
  }
  return j;
}

int run_modes(const std::vector<std::string>& argv) {
  const Args args(argv, {"--speed", "--fmax"}, {"--json", "--shapes", "--all"});
  args.expect_positional(1, "PLANT.json");
  const PlantModel plant = read_plant_file(args.positional()[0]);
  const double rpm = speed_of(args, plant);
  const double fmax_hz = args.number("--fmax").value_or(std::numeric_limits<double>::infinity());
  ModalOptions opt;
  opt.shapes = true;  // whirl direction and labels need the shapes
  opt.f_max_hz = fmax_hz;  // large models: the Krylov solver finds the modes below it
  const ModalResult r = modal_analysis(plant, rpm, opt);
  std::vector<const Mode*> shown;
  for (const auto& m : r.modes) {
    if (m.f_hz > fmax_hz) continue;
    // Zero-frequency (free rigid-body) and overdamped rotor roots only with --all.
    if (!args.flag("--all") && m.kind == "rotor" && (m.f_hz == 0.0 || m.overdamped)) continue;
    shown.push_back(&m);
  }
  if (args.flag("--json")) {
    json out = {{"model", plant.name}, {"speed_rpm", rpm}, {"modes", json::array()}};
    for (const Mode* m : shown) out["modes"].push_back(mode_json(*m, args.flag("--shapes")));
    std::cout << out.dump(2) << "\n";
    return kExitOk;
  }
  std::printf("%s at %.1f rpm: %zu modes\n", plant.name.c_str(), rpm, shown.size());
  std::printf("%10s %9s  %-9s %-8s %s\n", "f [Hz]", "zeta [%]", "direction", "whirl", "label");
  for (const Mode* m : shown) {
    std::printf("%10.3f %9.3f  %-9s %-8s %s\n", m->f_hz, 100.0 * m->zeta, m->direction.c_str(),
                m->whirl == Whirl::none ? "-" : to_string(m->whirl).c_str(), m->label.c_str());
  }
  return kExitOk;
}

int run_frf(const std::vector<std::string>& argv) {
  const Args args(argv, {"--speed", "--fmin", "--fmax", "--df", "-o", "--method"}, {});
  args.expect_positional(1, "PLANT.json");
  const auto out_path = args.option("-o");
  if (!out_path) throw UsageError("missing -o FRF.csv");
  const PlantModel plant = read_plant_file(args.positional()[0]);
  const double rpm = speed_of(args, plant);
  const auto freq = frequency_grid(args.number("--fmin").value_or(1.0), args.number("--fmax").value_or(1000.0),
                                   args.number("--df").value_or(1.0));
  FrfSynthesisOptions opt;
  const std::string method = args.option("--method").value_or("direct");
  if (method == "modal") {
    opt.method = FrfMethod::modal;
  } else if (method != "direct") {
    throw UsageError("--method: must be direct or modal");
  }
  Progress progress("model frf", static_cast<long>(freq.size()));
  FrfData frf = synthesize_frf(plant, rpm, freq, opt);
  progress.finish();
  frf.set_meta("model", plant.name);
  write_frf_csv(*out_path, frf);
  std::fprintf(stderr, "wrote %zu x %zu FRFs at %zu lines to %s\n", plant.sensors.size(), plant.actuators.size(),
               freq.size(), out_path->c_str());
  return kExitOk;
}

int run_campbell(const std::vector<std::string>& argv) {
  const Args args(argv, {"--speed-min", "--speed-max", "--steps", "--fmax", "--svg"}, {"--json"});
  args.expect_positional(1, "PLANT.json");
  const PlantModel plant = read_plant_file(args.positional()[0]);
  CampbellOptions opt;
  opt.speed_min_rpm = args.number("--speed-min").value_or(0.0);
  opt.speed_max_rpm = args.number("--speed-max").value_or(std::max(1.2 * plant.speed_rpm, 1000.0));
  opt.n_speeds = static_cast<int>(args.number("--steps").value_or(31));
  opt.f_max_hz = args.number("--fmax").value_or(1000.0);
  if (opt.speed_min_rpm < 0 || opt.speed_max_rpm < opt.speed_min_rpm) throw UsageError("need 0 <= --speed-min <= --speed-max");
  if (opt.n_speeds < 2 || opt.n_speeds > 2000) throw UsageError("--steps: must be in 2..2000");
  if (!(opt.f_max_hz > 0)) throw UsageError("--fmax: must be > 0");
  Progress progress("model campbell", opt.n_speeds);
  const CampbellResult r = campbell(plant, opt);
  progress.finish();
  if (auto svg = args.option("--svg")) write_file_atomic(*svg, campbell_svg(r, "Campbell diagram: " + plant.name));
  if (args.flag("--json")) {
    std::cout << campbell_to_json(r).dump(2) << "\n";
    return kExitOk;
  }
  std::printf("%s: %zu tracked modes below %.0f Hz over %.0f..%.0f rpm; %s\n", plant.name.c_str(), r.tracks.size(),
              opt.f_max_hz, opt.speed_min_rpm, opt.speed_max_rpm,
              r.stable ? "stable at every speed" : "UNSTABLE above some speed");
  std::printf("critical speeds (1x):\n");
  for (const auto& c : r.critical_speeds) {
    std::printf("  %9.1f rpm  %8.2f Hz  %-4s %-8s log dec %.3f\n", c.speed_rpm, c.f_hz, c.label.c_str(),
                to_string(c.whirl).c_str(), c.log_dec);
  }
  if (r.instability_onset_rpm) std::printf("onset of instability: %.1f rpm\n", *r.instability_onset_rpm);
  return kExitOk;
}

}  // namespace

std::vector<Command> model_commands() {
  return {
      {{"model", "modes"},
       "modal analysis of a plant model",
       "usage: ambdiag model modes PLANT.json [--speed RPM] [--fmax HZ] [--json] [--shapes] [--all]\n\n"
       "Natural frequencies, damping ratios and whirl directions of the plant model at a speed\n"
       "(default: the model's speed_rpm). Lateral rotor modes from the eigenvalues of the\n"
       "first-order form; housing and axial modes in closed form. Sorted by f_hz.\n\n"
       "  --speed RPM  rotor speed in rpm\n"
       "  --fmax HZ    list modes up to this frequency only (needed for models over 200 elements)\n"
       "  --json       one JSON document on stdout: {\"modes\": [{f_hz, zeta, direction, whirl, label, ...}]}\n"
       "  --shapes     include mode shapes (complex x, y per node) in the JSON\n"
       "  --all        also list zero-frequency and overdamped rotor roots\n",
       run_modes},
      {{"model", "frf"},
       "simulated FRF matrix of a plant model",
       "usage: ambdiag model frf PLANT.json -o FRF.csv [--fmin HZ] [--fmax HZ] [--df HZ] [--speed RPM]\n"
       "                         [--method direct|modal]\n\n"
       "Compliance FRFs (m/N) of every sensor over every actuator on the grid fmin:df:fmax\n"
       "(default 1:1:1000 Hz), written as an ambdiag.frf/1 file.\n\n"
       "  --method direct  sparse complex LU per line (default)\n"
       "  --method modal   superposition of the first-order eigenvectors\n",
       run_frf},
      {{"model", "campbell"},
       "Campbell diagram, critical speeds and stability",
       "usage: ambdiag model campbell PLANT.json [--speed-min RPM] [--speed-max RPM] [--steps N]\n"
       "                              [--fmax HZ] [--json] [--svg FILE]\n\n"
       "Modes over a speed range (default 0 .. 1.2 x the model's speed, 31 steps), tracked\n"
       "across speeds by mode-shape MAC (not re-sorted by frequency), with log decrements,\n"
       "critical speeds where a track crosses the 1x line, and the onset of instability.\n",
       run_campbell},
  };
}

}  // namespace ambdiag::cli
