// `ambdiag fit FRF.csv [--model PLANT.json]`: identified modal parameters,
// labelled against the model's modes when one is given (Table 3 layout).
#include <cmath>
#include <cstdio>
#include <iostream>
#include <optional>

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/identification/fit_report.h"
#include "ambdiag/algorithms/identification/mode_labels.h"
#include "ambdiag/algorithms/identification/rational_fit.h"
#include "ambdiag/algorithms/model/modal_analysis.h"
#include "ambdiag/core/error.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/io_util.h"
#include "ambdiag/core/plant_model.h"
#include "args.h"
#include "command.h"

namespace ambdiag::cli {

namespace {

using nlohmann::json;

void print_table(const ModePairing& pairing, const std::vector<Mode>* model) {
  struct Row {
    double f_sort;
    std::string text;
  };
  std::vector<Row> rows;
  char buf[256];
  for (const auto& d : pairing.identified) {
    const Mode* m = model && d.model_index >= 0 ? &(*model)[static_cast<size_t>(d.model_index)] : nullptr;
    std::string label = d.label.empty() ? (model ? "(not in model) " : "") + d.direction : d.label;
    if (m) {
      std::snprintf(buf, sizeof buf, "%-34s %9.2f %7.2f %7.2f   %9.2f %7.2f", label.c_str(), d.mode.f_hz, 100 * d.mode.zeta,
                    100 * d.mode.zeta_sd, m->f_hz, 100 * m->zeta);
    } else {
      std::snprintf(buf, sizeof buf, "%-34s %9.2f %7.2f %7.2f   %9s %7s", label.c_str(), d.mode.f_hz, 100 * d.mode.zeta,
                    100 * d.mode.zeta_sd, "-", "-");
    }
    rows.push_back({d.mode.f_hz, buf});
  }
  if (model) {
    for (int i : pairing.unmatched_model) {
      const Mode& m = (*model)[static_cast<size_t>(i)];
      std::string label = "(not detected) " + (m.label.empty() ? m.kind : m.label);
      if (m.whirl != Whirl::none) label += " (" + to_string(m.whirl) + ")";
      std::snprintf(buf, sizeof buf, "%-34s %9s %7s %7s   %9.2f %7.2f", label.c_str(), "-", "-", "", m.f_hz, 100 * m.zeta);
      rows.push_back({m.f_hz, buf});
    }
  }
  std::sort(rows.begin(), rows.end(), [](const Row& a, const Row& b) { return a.f_sort < b.f_sort; });
  std::printf("%-34s %9s %7s %7s   %9s %7s\n", "mode", "f [Hz]", "zeta[%]", "sd[%]", "model f", "zeta[%]");
  for (const auto& r : rows) std::printf("%s\n", r.text.c_str());
}

int run_fit(const std::vector<std::string>& argv) {
  const Args args(argv, {"--model", "--fmin", "--fmax", "--modes", "--max-modes", "--svg", "--speed"}, {"--json", "--no-delay"});
  args.expect_positional(1, "FRF.csv");
  const FrfData frf = read_frf_csv(args.positional()[0]);
  RationalFitOptions opt;
  opt.f_min_hz = args.number("--fmin").value_or(0.0);
  opt.f_max_hz = args.number("--fmax").value_or(0.0);
  opt.modes = static_cast<int>(args.number("--modes").value_or(0));
  opt.max_modes = static_cast<int>(args.number("--max-modes").value_or(opt.max_modes));
  opt.estimate_delay = !args.flag("--no-delay");
  std::string why;
  if (!opt.is_valid(&why)) throw UsageError(why);

  std::optional<PlantModel> plant;
  if (auto m = args.option("--model")) plant = read_plant_file(*m);

  std::fprintf(stderr, "fit: %zu entries, %zu lines ...\n", frf.entries.size(), frf.freq_hz.size());
  RationalFitResult fit;
  try {
    fit = fit_rational(frf, opt);
  } catch (const InputError& e) {
    rethrow_with_context(e, args.positional()[0]);
  }
  if (fit.modes.empty())
    std::fprintf(stderr, "warning: %s: no mode rises above the noise (chi2/dof %.3g of the %d-pole-pair model)\n",
                 args.positional()[0].c_str(), fit.report.chi2_per_dof, fit.model.pair_count());
  if (fit.report.delay_fitted)
    std::fprintf(stderr, "fit: a pure delay of %.3g us (sd %.2g us) is fitted as e^(-j w tau)\n", 1e6 * fit.report.delay_s,
                 1e6 * fit.report.delay_sd_s);

  std::vector<ModeDescription> described;
  for (const auto& m : fit.modes) described.push_back(describe_mode(m, fit, frf, plant ? &*plant : nullptr));
  std::vector<Mode> model_modes;
  const double f_lo = opt.f_min_hz > 0 ? opt.f_min_hz : frf.freq_hz.front();
  const double f_hi = opt.f_max_hz > 0 ? opt.f_max_hz : frf.freq_hz.back();
  if (plant) {
    const double rpm = args.number("--speed").value_or(frf.speed_rpm.value_or(plant->speed_rpm));
    model_modes = modal_analysis(*plant, rpm).modes;
  }
  const ModePairing pairing = plant ? pair_with_model(described, model_modes, f_lo, f_hi) : ModePairing{described, {}, {}};

  if (auto svg = args.option("--svg")) write_file_atomic(*svg, stabilization_svg(fit, frf));

  if (args.flag("--json")) {
    const json out = fit_to_json(fit, pairing, plant ? &model_modes : nullptr);
    std::cout << out.dump(2) << "\n";
    return kExitOk;
  }
  int order = 0;
  for (const auto& p : fit.model.poles) order += p.imag() == 0.0 ? 1 : 2;
  std::printf("%zu modes identified (%d pole pairs, order %d, chi2/dof %.3f%s)\n", fit.modes.size(), fit.model.pair_count(),
              order, fit.report.chi2_per_dof, fit.report.sigma_from_data ? "" : ", no sigma in the file");
  if (fit.report.delay_fitted)
    std::printf("pure delay fitted: %.3f us (sd %.3f us)\n", 1e6 * fit.report.delay_s, 1e6 * fit.report.delay_sd_s);
  print_table(pairing, plant ? &model_modes : nullptr);
  return kExitOk;
}

}  // namespace

std::vector<Command> fit_commands() {
  return {{{"fit"},
           "identified modal parameters of an FRF matrix",
           "usage: ambdiag fit FRF.csv [--model PLANT.json] [--json] [--fmin HZ] [--fmax HZ]\n"
           "                  [--modes N | --max-modes N] [--svg STABILIZATION.svg] [--speed RPM] [--no-delay]\n\n"
           "Fits one rational model with common poles to every FRF entry that carries signal\n"
           "(vector fitting, then maximum likelihood weighted by the sigma_ columns), chooses the\n"
           "order automatically (BIC) unless --modes is given, and reports natural frequency,\n"
           "damping ratio, their standard deviations, direction, whirl and which sensors and\n"
           "actuators see each mode. With --model, modes are paired with the plant model's modes\n"
           "(at the file's speed_rpm) in the layout of Nordmann & Aenis' Table 3.\n"
           "A pure delay e^(-j w tau) of the whole matrix (acquisition delay) is fitted and reported\n"
           "when the data show one (--no-delay: never). No mode above the noise: exit 0, warning.\n",
           run_fit}};
}

}  // namespace ambdiag::cli
