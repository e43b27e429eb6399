// `ambdiag model modes|frf`: the plant model's modes and FRF matrix.
#include <cstdio>
#include <limits>
#include <iostream>

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/frf_synthesis.h"
#include "ambdiag/algorithms/modal_analysis.h"
#include "ambdiag/core/frf_data.h"
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
  ModalOptions opt;
  opt.shapes = true;  // whirl direction and labels need the shapes
  const ModalResult r = modal_analysis(plant, rpm, opt);
  const double fmax_hz = args.number("--fmax").value_or(std::numeric_limits<double>::infinity());
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
       "  --fmax HZ    list modes up to this frequency only\n"
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
  };
}

}  // namespace ambdiag::cli
