#include "run_analysis.h"

#include <algorithm>
#include <cmath>

#include "ambdiag/algorithms/diagnosis/diagnosis_report.h"
#include "ambdiag/algorithms/estimation/frf_estimation.h"
#include "ambdiag/algorithms/explain/explain.h"
#include "ambdiag/algorithms/explain/missing_physics.h"
#include "ambdiag/algorithms/identification/fit_report.h"
#include "ambdiag/algorithms/identification/mode_labels.h"
#include "ambdiag/algorithms/identification/rational_fit.h"
#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/algorithms/model/modal_analysis.h"
#include "ambdiag/core/error.h"
#include "analysis/fit_model_file.h"

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;

void report(const ProgressFn& p, double share) {
  if (p) p(std::clamp(share, 0.0, 1.0));
}

storage::JobArtifact svg(std::string name, std::string text) {
  return {std::move(name), "image/svg+xml", std::move(text)};
}

}  // namespace

PlantModel plant_from_text(const std::string& plant_json, const std::string& source) {
  json doc;
  try {
    doc = json::parse(plant_json);
  } catch (const json::exception& e) {
    throw InputError(source + ": not JSON: " + e.what());
  }
  try {
    // explain's improved models carry "acquisition": {"delay_s"}, which the
    // plant reader ignores; the plant itself is what the analysis uses.
    return plant_from_json(doc);
  } catch (const InputError& e) {
    rethrow_with_context(e, source);
  }
}

FrfData estimate_run_frf(const RunRecording& run, json* summary) {
  FrfEstimate est;
  try {
    est = estimate_frf(run);
  } catch (const InputError& e) {
    rethrow_with_context(e, "run " + run.run_id);
  }
  if (summary)
    *summary = {{"method", est.method},
                {"lines", est.frf.freq_hz.size()},
                {"lines_dropped", est.lines_dropped},
                {"entries", est.frf.entries.size()},
                {"averages", est.averages},
                {"sigma_dof", est.sigma_dof},
                {"f_min_hz", est.frf.freq_hz.empty() ? 0.0 : est.frf.freq_hz.front()},
                {"f_max_hz", est.frf.freq_hz.empty() ? 0.0 : est.frf.freq_hz.back()},
                {"warnings", est.warnings}};
  return std::move(est.frf);
}

JobOutput analyse_run(const PlantModel& plant, const RunRecording& run, const OperatingReference* reference,
                      double alpha, const ProgressFn& progress) {
  JobOutput out;
  json& r = out.result;
  const double speed_rpm = run.speed_rpm > 0 ? run.speed_rpm : plant.speed_rpm;
  r["speed_rpm"] = speed_rpm;
  try {
    run.validate_against(plant);
  } catch (const InputError& e) {
    rethrow_with_context(e, "run " + run.run_id + " against the pump's model");
  }
  report(progress, 0.02);

  json frf_summary;
  FrfData frf = estimate_run_frf(run, &frf_summary);
  if (!frf.speed_rpm) frf.speed_rpm = speed_rpm;
  r["frf"] = frf_summary;
  out.artifacts.push_back({"frf.csv", "text/csv", format_frf_csv(frf)});
  report(progress, 0.3);

  // Modal fit, labelled against the model at the run's own speed. The
  // automatic order search is bounded by the model's modes in the band plus
  // room for 8 it lacks (explain finds those): unbounded, BIC took 28 pole
  // pairs on a simulated healthy run of a pump with 12 modes in the band
  // (chi2/dof 0.88: noise and the synchronous lines fitted), labelled 6 of
  // them instead of 9 and cost twice the CPU (1.9 s against 0.96 s).
  const std::vector<Mode> model_modes = modal_analysis(plant, speed_rpm).modes;
  RationalFitOptions fit_opt;
  int in_band = 0;
  for (const auto& m : model_modes) in_band += m.f_hz >= frf.freq_hz.front() && m.f_hz <= frf.freq_hz.back() ? 1 : 0;
  fit_opt.max_modes = std::clamp(in_band + 8, 8, fit_opt.max_modes);
  r["fit_max_pole_pairs"] = fit_opt.max_modes;
  RationalFitResult fit;
  try {
    fit = fit_rational(frf, fit_opt);
  } catch (const InputError& e) {
    rethrow_with_context(e, "fit of run " + run.run_id);
  }
  std::vector<ModeDescription> described;
  for (const auto& m : fit.modes) described.push_back(describe_mode(m, fit, frf, &plant));
  const ModePairing pairing = pair_with_model(described, model_modes, frf.freq_hz.front(), frf.freq_hz.back());
  const json fit_json = fit_to_json(fit, pairing, &model_modes, false);
  r["modes"] = fit_json["modes"];
  r["unmatched_model_modes"] = fit_json["unmatched_model_modes"];
  r["unmatched_identified_modes"] = fit_json["unmatched_identified_modes"];
  r["fit"] = fit_json["fit"];
  r["fit"]["order"] = fit_json["order"];
  r["fit"]["pole_pairs"] = fit_json["pole_pairs"];
  out.artifacts.push_back(svg("stabilization.svg", stabilization_svg(fit, frf)));
  out.artifacts.push_back({"fit_model.json", "application/json", fit_model_json(fit, frf).dump()});
  report(progress, 0.75);

  const FrfData model = model_frf_like(plant, frf);
  const FrfComparison cmp = compare_frf(model, frf);
  r["nrmse"] = cmp.nrmse;
  char title[160];
  std::snprintf(title, sizeof title, "%s: measured (solid) vs model (dashed) at %.0f rpm, NRMSE %.3f", run.run_id.c_str(),
                speed_rpm, cmp.nrmse);
  out.artifacts.push_back(svg("bode.svg", bode_svg(frf, model, title)));
  report(progress, 0.8);

  r["detection"] = nullptr;
  r["diagnosis"] = nullptr;
  if (reference) {
    DiagnosisOptions opt;
    opt.alpha = alpha;
    opt.progress = [&](const std::string&, int done, int total) {
      if (total > 0) report(progress, 0.8 + 0.19 * done / total);
    };
    const DiagnosisResult d = diagnose(plant, *reference, frf, opt);
    r["detection"] = {{"detected", d.detected},
                      {"statistic", d.statistic},
                      {"threshold", d.threshold},
                      {"false_alarm_rate", d.alpha},
                      {"ratio", d.threshold > 0 ? d.statistic / d.threshold : 0.0},
                      {"dof", d.dof},
                      {"p_value", d.p_value}};
    // Both tests and the fitted seal factors of every run, not only of
    // detected ones: how close a healthy run came, and its seal drift.
    if (d.operating.used) r["detection"]["operating"] = operating_tests_to_json(d.operating);
    if (d.detected) {
      r["diagnosis"] = diagnosis_to_json(d, plant);
      out.artifacts.push_back(svg("diagnosis.svg", diagnosis_svg(d, frf)));
    }
  }
  report(progress, 1.0);
  return out;
}

JobOutput learn_reference(const PlantModel& plant, const std::vector<FrfData>& frfs, const std::vector<std::string>& run_ids,
                          const ProgressFn& progress) {
  JobOutput out;
  report(progress, 0.1);
  const OperatingReference ref = learn_operating_reference(plant, frfs);
  report(progress, 0.9);
  json speeds = json::array();
  for (const auto& f : frfs) speeds.push_back(f.speed_rpm ? json(*f.speed_rpm) : json(nullptr));
  // What was learnt, for the engineer who chose the runs: each run's seal
  // factors and how well model + bias reproduce it (chi2 per value, 1 at
  // the noise), the normal spread used, and how far the model is from the
  // runs (the bias b: NRMSE of b against the runs' mean |H|). A large bias
  // is either an imperfect model or a pump that was not healthy when the
  // runs were recorded: `explain` on a reference run tells which.
  json runs = json::array();
  for (const auto& run : ref.runs) {
    json factors = json::object();
    for (size_t k = 0; k < run.log_factor.size() && k < ref.nuisance_links.size(); ++k)
      factors[ref.nuisance_links[k]] = std::exp(run.log_factor[k]);
    runs.push_back({{"run_id", run.run_id},
                    {"speed_rpm", run.speed_rpm},
                    {"seal_factors", factors},
                    {"chi2_per_value", run.values > 0 ? run.chi2 / run.values : 0.0}});
  }
  double bias2 = 0.0, h2 = 0.0;
  for (const auto& e : ref.entries)
    for (const auto& b : e.bias) bias2 += std::norm(b);
  for (const auto& f : frfs)
    for (const auto& e : f.entries)
      for (const auto& h : e.h) h2 += std::norm(h) / static_cast<double>(frfs.size());
  out.result = {{"runs", run_ids},
                {"speeds_rpm", speeds},
                {"learnt", runs},
                {"common_sd", ref.common_sd},
                {"link_sd", ref.link_sd},
                {"common_sd_estimate", ref.common_sd_estimate},
                {"link_sd_estimate", ref.link_sd_estimate},
                {"model_bias_nrmse", h2 > 0 ? std::sqrt(bias2 / h2) : 0.0}};
  out.artifacts.push_back({"reference.json", "application/json", operating_reference_to_json(ref)});
  report(progress, 1.0);
  return out;
}

JobOutput explain_run(const PlantModel& plant, const FrfData& frf, const ProgressFn& progress) {
  JobOutput out;
  ExplainOptions opt;
  int stage = 0;
  // explain reports stages, not shares: each of its up to max_steps
  // selection steps moves the bar by an equal part.
  opt.progress = [&](const std::string&) { report(progress, std::min(0.95, ++stage / (opt.max_steps + 4.0))); };
  const ExplainResult r = explain(plant, frf, opt);
  out.result = explain_to_json(r);
  out.artifacts.push_back({"improved_model.json", "application/json", variant_to_json(r.improved).dump(2) + "\n"});
  out.artifacts.push_back(svg("explain.svg", explain_svg(r, frf)));
  report(progress, 1.0);
  return out;
}

}  // namespace ambdiag::server::detail
