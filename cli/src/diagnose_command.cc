// `ambdiag diagnose --model PLANT.json --reference REF.csv [REF2.csv ...]
// --measured FRF.csv [--json] [--svg FILE]`: detection and ranked fault
// diagnosis (../shared/specs/cli.md, docs/diagnosis.md).
#include <cmath>
#include <cstdio>
#include <iostream>

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/diagnosis/diagnosis.h"
#include "ambdiag/algorithms/diagnosis/diagnosis_report.h"
#include "ambdiag/algorithms/diagnosis/operating_reference.h"
#include "ambdiag/algorithms/identification/modal_features.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/io_util.h"
#include "ambdiag/core/plant_model.h"
#include "args.h"
#include "command.h"

namespace ambdiag::cli {

namespace {

using nlohmann::json;

void print_text(const DiagnosisResult& r) {
  std::printf("detection: %s (chi2 %.1f, threshold %.1f at false-alarm rate %g, dof %.0f, p %.3g)\n",
              r.detected ? "CHANGED" : "no change", r.statistic, r.threshold, r.alpha, r.dof, r.p_value);
  if (r.operating.used) {
    const OperatingTests& t = r.operating;
    std::printf("  at %.1f rpm; residual after the seal drift: chi2 %.1f, threshold %.1f (p %.3g); drift: %.2f, threshold %.2f (p %.3g)\n",
                t.speed_rpm, t.residual_statistic, t.residual_threshold, t.residual_p_value, t.drift_statistic, t.drift_threshold,
                t.drift_p_value);
    for (const auto& n : t.nuisance)
      std::printf("  seal drift %-20s %+.2f %% (normal +-%.2f %%)\n", n.link.c_str(), 100.0 * std::expm1(n.log_factor), 100.0 * n.normal_sd);
  }
  if (!r.detected) return;
  std::printf("isolation: %s\n", r.isolation.c_str());
  for (const auto& s : r.symptoms) {
    if (s.kind == "entry") std::printf("  symptom: H %s/%s chi2 %.0f over %.0f dof\n", s.output.c_str(), s.input.c_str(), s.statistic, s.dof);
    if (s.kind == "band") std::printf("  symptom: %.0f %% of the change in %.0f-%.0f Hz\n", 100 * s.statistic, s.band_lo_hz, s.band_hi_hz);
  }
  std::printf("%-22s %-26s %-18s %12s %18s %8s\n", "fault", "location", "parameter", "value", "95 % interval", "score");
  for (const auto& f : r.faults) {
    if (f.name == "unknown") {
      std::printf("%-22s (no fault model brings the residual to the noise floor)\n", "unknown");
      continue;
    }
    char ci[64];
    std::snprintf(ci, sizeof ci, "[%.3g, %.3g]", f.ci_lo, f.ci_hi);
    std::printf("%-22s %-26s %-18s %12.4g %18s %8.3g\n", f.name.c_str(), f.location.c_str(), f.hypothesis.parameter.c_str(), f.value, ci,
                f.score);
  }
  std::printf("fit: NRMSE model vs measured before %.4f, after %.4f (chi2 %.0f -> %.0f)\n", r.nrmse_before, r.nrmse_after, r.chi2_before,
              r.chi2_after);
  for (const auto& s : r.not_assessed) std::printf("not assessed: %s\n", s.c_str());
}

json feature_json(const ModalFeatureReference& ref, const ModalFeatureTest& t) {
  json j = {{"statistic", t.statistic}, {"threshold", t.threshold}, {"dof", t.dof}, {"p_value", t.p_value}, {"detected", t.detected},
            {"modes", json::array()}, {"missing", json::array()}, {"new", json::array()}};
  for (const auto& s : t.shifts) {
    if (s.reference_mode < 0) {
      j["new"].push_back({{"f_hz", s.f_hz}, {"zeta", s.zeta}});
      continue;
    }
    const auto& m = ref.modes[static_cast<size_t>(s.reference_mode)];
    j["modes"].push_back({{"direction", m.direction}, {"f_ref_hz", m.f_hz}, {"zeta_ref", m.zeta}, {"f_hz", s.f_hz},
                          {"zeta", s.zeta}, {"z_f", s.z_f}, {"z_zeta", s.z_zeta}});
  }
  for (int k : t.missing)
    j["missing"].push_back({{"f_ref_hz", ref.modes[static_cast<size_t>(k)].f_hz}, {"zeta_ref", ref.modes[static_cast<size_t>(k)].zeta}});
  return j;
}

void print_features(const ModalFeatureReference& ref, const ModalFeatureTest& t) {
  std::printf("modal features: %s (chi2 %.1f, threshold %.1f, dof %.0f)\n", t.detected ? "CHANGED" : "no change", t.statistic,
              t.threshold, t.dof);
  std::printf("  %-8s %10s %8s %10s %8s %8s %8s\n", "dir", "f_ref Hz", "zeta_ref", "f Hz", "zeta", "z_f", "z_zeta");
  for (const auto& s : t.shifts) {
    if (s.reference_mode < 0) {
      std::printf("  %-8s %10s %8s %10.2f %8.4f   (new)\n", "", "-", "-", s.f_hz, s.zeta);
      continue;
    }
    const auto& m = ref.modes[static_cast<size_t>(s.reference_mode)];
    std::printf("  %-8s %10.2f %8.4f %10.2f %8.4f %8.1f %8.1f\n", m.direction.c_str(), m.f_hz, m.zeta, s.f_hz, s.zeta, s.z_f, s.z_zeta);
  }
  for (int k : t.missing) std::printf("  %-8s %10.2f %8.4f   (not found)\n", "", ref.modes[static_cast<size_t>(k)].f_hz, ref.modes[static_cast<size_t>(k)].zeta);
}

int run_diagnose(const std::vector<std::string>& argv) {
  const Args args(argv, {"--model", "--measured", "--svg", "--alpha", "--save-reference"}, {"--json", "--features", "--same-speed"},
                  {"--reference"});
  if (!args.positional().empty()) throw UsageError("unexpected argument '" + args.positional()[0] + "'");
  const auto model_path = args.option("--model");
  const auto measured_path = args.option("--measured");
  const auto refs = args.values("--reference");
  if (!model_path) throw UsageError("--model PLANT.json is required");
  if (!measured_path) throw UsageError("--measured FRF.csv is required");
  if (refs.empty()) throw UsageError("--reference REF.csv [REF2.csv ...] is required");
  DiagnosisOptions opt;
  opt.alpha = args.number("--alpha").value_or(opt.alpha);
  std::string why;
  if (!opt.is_valid(&why)) throw UsageError(why);

  const PlantModel plant = read_plant_file(*model_path);
  std::vector<FrfData> ref_runs;
  for (const auto& r : refs) ref_runs.push_back(read_frf_csv(r));
  const FrfData measured = read_frf_csv(*measured_path);
  std::fprintf(stderr, "diagnose: %zu references, %zu entries x %zu lines\n", ref_runs.size(), measured.entries.size(),
               measured.freq_hz.size());
  // Default: the operating reference (references at any speed, seal drift
  // learnt); --same-speed: the reference statistics of identical runs.
  const bool same_speed = args.flag("--same-speed");
  ReferenceStatistics ref;
  OperatingReference oref;
  if (same_speed) {
    ref = reference_statistics(ref_runs);
  } else {
    std::fprintf(stderr, "diagnose: learning the operating reference (model at each run's speed, seal drift)\n");
    oref = learn_operating_reference(plant, ref_runs);
    if (auto path = args.option("--save-reference")) write_file_atomic(*path, operating_reference_to_json(oref));
  }
  Progress bar("diagnose", 100);
  opt.progress = [&](const std::string& stage, int done, int total) {
    static std::string last;
    if (stage != last) std::fprintf(stderr, "diagnose: %s\n", stage.c_str()), last = stage;
    bar.update(total > 0 ? 100L * done / total : 0);
  };
  const DiagnosisResult r = same_speed ? diagnose(plant, ref, measured, opt) : diagnose(plant, oref, measured, opt);
  bar.finish();
  if (auto svg = args.option("--svg")) write_file_atomic(*svg, diagnosis_svg(r, measured));
  json features;
  if (args.flag("--features")) {
    std::fprintf(stderr, "diagnose: modal features (rational fit of %zu runs) ...\n", ref_runs.size() + 1);
    const ModalFeatureReference fref = modal_feature_reference(ref_runs);
    const ModalFeatureTest ft = modal_feature_test(fref, measured, opt.alpha);
    features = feature_json(fref, ft);
    if (!args.flag("--json")) {
      print_text(r);
      print_features(fref, ft);
      return kExitOk;
    }
  }

  if (!args.flag("--json")) {
    print_text(r);
    return kExitOk;
  }
  json out = diagnosis_to_json(r, plant);
  json rj;
  if (same_speed) {
    rj = {{"runs", ref.runs}, {"entries", json::array()}};
    for (const auto& e : ref.entries)
      if (e.kappa != 1.0 || !e.sigma_stated)
        rj["entries"].push_back({{"output", e.output}, {"input", e.input}, {"kappa", e.kappa}, {"sigma_stated", e.sigma_stated}});
  } else {
    json speeds = json::array();
    for (const auto& run : oref.runs) speeds.push_back(run.speed_rpm);
    rj = {{"runs", oref.runs.size()}, {"speeds_rpm", speeds}, {"common_sd", oref.common_sd}, {"link_sd", oref.link_sd},
          {"entries", json::array()}};
    for (const auto& e : oref.entries)
      if (e.kappa != 1.0) rj["entries"].push_back({{"output", e.output}, {"input", e.input}, {"kappa", e.kappa}, {"sigma_stated", true}});
  }
  out["reference"] = rj;
  if (!features.is_null()) out["features"] = features;
  std::cout << out.dump(2) << "\n";
  return kExitOk;
}

}  // namespace

std::vector<Command> diagnose_commands() {
  return {{{"diagnose"},
           "detection and ranked fault diagnosis against reference runs",
           "usage: ambdiag diagnose --model PLANT.json --reference REF.csv [REF2.csv ...] --measured FRF.csv\n"
           "                        [--json] [--svg FILE] [--alpha P] [--features] [--same-speed]\n"
           "                        [--save-reference FILE.json]\n\n"
           "Detection under operating conditions: the model at each run's speed (speed_rpm of its file),\n"
           "the fluid-seal drift (links of kind seal, balance_piston) fitted per run; a residual test (what\n"
           "the drift cannot explain, weighted by the sigma_ columns) and a drift test (against the spread\n"
           "learnt from the references, at least 3 % common and 1 % per seal), false-alarm rate --alpha per\n"
           "run (default 0.01; 1e-5 for monitoring every hour). References may run at other speeds than the\n"
           "measurement. --same-speed: the older test against the mean of identical reference runs.\n"
           "--save-reference writes the learnt operating reference (JSON). When detected, every fault model of the plant (dry run,\n"
           "balance piston and impeller seal wear, rotor crack by element, shaft nut loosening at the\n"
           "impeller hub, sensor and actuator gain) is fitted to the measured change by weighted least\n"
           "squares, scored by BIC and ranked; 'unknown' comes first when none brings the residual to the\n"
           "noise floor. Unbalance and misalignment need monitoring runs and are reported as not assessed.\n"
           "--features adds modal features (rational fit of every run, ~1 s each): reference modes, their\n"
           "normalised shifts in the measured run and a chi-square test on them (Table 4 of the paper).\n"
           "--svg writes measured vs model (healthy and best fault) for the entries that changed most.\n"
           "Progress on stderr. Exit 0 ok, 2 usage, 3 bad input (file named). See docs/diagnosis.md.\n",
           run_diagnose}};
}

}  // namespace ambdiag::cli
