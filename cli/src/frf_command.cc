// `ambdiag frf RUN_DIR -o FRF.csv`: the FRF matrix estimated from a
// time-domain run recording (algorithms/frf_estimation.h).
#include <cstdio>
#include <iostream>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/estimation/frf_estimation.h"
#include "ambdiag/algorithms/identification/fit_report.h"
#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/core/error.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/io_util.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/run_recording.h"
#include "args.h"
#include "command.h"

namespace ambdiag::cli {

namespace {

int run_frf_estimate(const std::vector<std::string>& argv) {
  const Args args(argv, {"-o", "--plant", "--method", "--nfft", "--svg"}, {"--json"});
  args.expect_positional(1, "RUN_DIR");
  const auto out_path = args.option("-o");
  if (!out_path) throw UsageError("missing -o FRF.csv");
  FrfEstimationOptions opt;
  const std::string method = args.option("--method").value_or("auto");
  if (method == "gated") {
    opt.method = NonperiodicMethod::gated;
  } else if (method == "lpm") {
    opt.method = NonperiodicMethod::lpm;
  } else if (method == "welch") {
    opt.method = NonperiodicMethod::welch;
  } else if (method == "h1") {
    opt.method = NonperiodicMethod::h1;
  } else if (method == "hv") {
    opt.method = NonperiodicMethod::hv;
  } else if (method != "auto") {
    throw UsageError("--method: must be auto, gated, lpm, welch, h1 or hv");
  }
  if (const auto n = args.number("--nfft")) {
    if (!(*n >= 4 && *n <= 1 << 24 && *n == static_cast<double>(static_cast<long>(*n)) &&
          static_cast<long>(*n) % 2 == 0)) {
      throw UsageError("--nfft: must be an even number of samples >= 4");
    }
    opt.nfft = static_cast<long>(*n);
  }

  const std::string dir = args.positional()[0];
  if (args.option("--svg") && !args.option("--plant")) throw UsageError("--svg needs --plant PLANT.json (measured vs model)");
  Progress progress("frf", 3);
  const RunRecording run = read_run(dir);
  std::optional<PlantModel> plant;
  if (const auto plant_path = args.option("--plant")) {
    plant = read_plant_file(*plant_path);
    try {
      run.validate_against(*plant);
    } catch (const InputError& e) {
      rethrow_with_context(e, dir + " (against " + *plant_path + ")");
    }
  }
  progress.update(1);
  FrfEstimate est;
  try {
    est = estimate_frf(run, opt);
  } catch (const InputError& e) {
    rethrow_with_context(e, dir);
  }
  progress.update(2);
  write_frf_csv(*out_path, est.frf);
  if (const auto svg = args.option("--svg")) {
    // The model at the run's speed on the estimate's grid (cli.md "Speed").
    const FrfData model = model_frf_like(*plant, est.frf);
    write_file_atomic(*svg, bode_svg(est.frf, model, dir + ": measured (solid) vs model (dashed), NRMSE " +
                                                         std::to_string(compare_frf(model, est.frf).nrmse).substr(0, 5)));
  }
  progress.finish();

  for (const auto& w : est.warnings)
    std::fprintf(stderr, "ambdiag frf: warning: %s: %s\n", dir.c_str(), w.c_str());
  const size_t n_out = est.frf.outputs().size(), n_in = est.frf.inputs().size();
  if (args.flag("--json")) {
    nlohmann::json j = {{"run", dir},
                        {"output", *out_path},
                        {"method", est.method},
                        {"lines", est.frf.freq_hz.size()},
                        {"lines_dropped", est.lines_dropped},
                        {"entries", est.frf.entries.size()},
                        {"outputs", est.frf.outputs()},
                        {"inputs", est.frf.inputs()},
                        {"averages", est.averages},
                        {"quantity", to_string(est.frf.quantity)},
                        {"unit", est.frf.unit},
                        {"f_min_hz", est.frf.freq_hz.front()},
                        {"f_max_hz", est.frf.freq_hz.back()},
                        {"warnings", est.warnings}};
    std::cout << j.dump(2) << "\n";
  } else {
    std::printf(
        "%s: %zu x %zu FRFs (%s, %s) at %zu lines %g..%g Hz, method %s, %ld averages%s\n", dir.c_str(), n_out,
        n_in, to_string(est.frf.quantity).c_str(), est.frf.unit.c_str(), est.frf.freq_hz.size(),
        est.frf.freq_hz.front(), est.frf.freq_hz.back(), est.method.c_str(), est.averages,
        est.warnings.empty() ? "" : (", " + std::to_string(est.warnings.size()) + " warning(s)").c_str());
  }
  std::fprintf(stderr, "wrote %s\n", out_path->c_str());
  return kExitOk;
}

}  // namespace

std::vector<Command> estimate_commands() {
  return {
      {{"frf"},
       "FRF matrix estimated from a time-domain run recording",
       "usage: ambdiag frf RUN_DIR -o FRF.csv [--plant PLANT.json [--svg BODE.svg]] [--method M] [--nfft N] [--json]\n\n"
       "Estimates H = response / input (with sigma_ and coh_ columns) from a run recording and writes\n"
       "an ambdiag.frf/1 file. Inputs are the measured forces, with the noise-free references as\n"
       "instruments (unbiased in the closed AMB loop); runs without force channels give H relative to\n"
       "the reference. By excitation type:\n"
       "  multisine  per segment the settle periods dropped, the periods' DFTs averaged; X = H F per line\n"
       "  stepsine   lock-in DFT of each step's whole periods; the steps at one frequency solved together\n"
       "  chirp      whole-sweep spectra, impulse responses time-gated (noise outside the gate removed)\n"
       "  random     Welch averaging (Hann, 50 % overlap)\n"
       "Warnings (dropped lines or segments, no sigma) go to stderr and to `# warning_N:` lines of the\n"
       "file. A run that gives no trustworthy estimate (clipped or dead channel, zero reference, too\n"
       "few independent segments) exits 3 with the reason.\n\n"
       "  -o FRF.csv       output file\n"
       "  --plant FILE     check that every channel names a sensor or actuator of this plant model\n"
       "  --svg FILE       with --plant: |H| and unwrapped phase of the four strongest entries, measured vs\n"
       "                   the model at the run's speed\n"
       "  --method M       chirp and random runs: auto (gated for a chirp, welch for random), gated,\n"
       "                   lpm (local polynomial method on whole segments), welch (references as\n"
       "                   instruments; H1 when the input is the reference), h1 (S_xf S_ff^-1 on the\n"
       "                   measured inputs, biased in closed loop), hv (total least squares)\n"
       "  --nfft N         Welch window length in samples (default: from the run length)\n"
       "  --json           print a JSON summary on stdout: method, lines, entries, warnings, ...\n",
       run_frf_estimate},
  };
}

}  // namespace ambdiag::cli
