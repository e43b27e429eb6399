#include "ambdiag/algorithms/identification/fit_report.h"

#include <algorithm>
#include <cmath>

#include "ambdiag/core/svg_plot.h"

namespace ambdiag {

namespace {

using nlohmann::json;

json identified_json(const ModeDescription& d, const std::vector<Mode>* model) {
  json j = {{"f_hz", d.mode.f_hz},       {"zeta", d.mode.zeta},       {"f_sd_hz", d.mode.f_sd_hz},
            {"zeta_sd", d.mode.zeta_sd}, {"direction", d.direction}, {"whirl", to_string(d.whirl)},
            {"outputs", d.outputs},      {"inputs", d.inputs},       {"peak_snr", d.mode.peak_snr},
            {"stable_orders", d.mode.stable_orders}};
  if (!d.label.empty()) j["label"] = d.label;
  if (model && d.model_index >= 0) {
    const Mode& m = (*model)[static_cast<size_t>(d.model_index)];
    j["model_f_hz"] = m.f_hz;
    j["model_zeta"] = m.zeta;
  }
  return j;
}

json model_mode_json(const Mode& m) {
  json j = {{"f_hz", m.f_hz}, {"zeta", m.zeta}, {"direction", m.direction}, {"whirl", to_string(m.whirl)}};
  if (!m.label.empty()) j["label"] = m.label;
  return j;
}

}  // namespace

json fit_to_json(const RationalFitResult& fit, const ModePairing& pairing, const std::vector<Mode>* model_modes,
                 bool with_stabilization) {
  int order = 0;
  for (const auto& p : fit.model.poles) order += p.imag() == 0.0 ? 1 : 2;
  json out = {{"order", order},
              {"pole_pairs", fit.model.pair_count()},
              {"numerator_power", fit.numerator_power},
              {"modes", json::array()},
              {"fit",
               {{"chi2_per_dof", fit.report.chi2_per_dof},
                {"converged", fit.report.converged},
                {"stop_reason", fit.report.stop_reason},
                {"ml_iterations", fit.report.ml_iterations},
                {"entries_fitted", fit.entries.size()},
                {"sigma_from_data", fit.report.sigma_from_data},
                {"delay_fitted", fit.report.delay_fitted},
                {"delay_s", fit.report.delay_s},
                {"delay_sd_s", fit.report.delay_sd_s}}}};
  for (const auto& d : pairing.identified) out["modes"].push_back(identified_json(d, model_modes));
  if (model_modes) {
    out["unmatched_model_modes"] = json::array();
    for (int i : pairing.unmatched_model)
      out["unmatched_model_modes"].push_back(model_mode_json((*model_modes)[static_cast<size_t>(i)]));
    out["unmatched_identified_modes"] = json::array();
    for (int i : pairing.unmatched_identified)
      out["unmatched_identified_modes"].push_back(identified_json(pairing.identified[static_cast<size_t>(i)], nullptr));
  }
  if (with_stabilization) {
    out["stabilization"] = json::array();
    for (const auto& row : fit.stabilization) {
      json poles = json::array();
      for (size_t k = 0; k < row.poles.size(); ++k)
        poles.push_back({{"f_hz", std::abs(row.poles[k]) / (2 * M_PI)},
                         {"zeta", -row.poles[k].real() / std::abs(row.poles[k])},
                         {"stable", static_cast<bool>(row.stable[k])}});
      out["stabilization"].push_back({{"pole_pairs", row.modes}, {"criterion", row.criterion}, {"poles", poles}});
    }
  }
  return out;
}

std::string stabilization_svg(const RationalFitResult& fit, const FrfData& frf) {
  SvgFigure fig;
  fig.title = "Stabilization diagram (selected: " + std::to_string(fit.selected_modes) + " pole pairs)";
  fig.x_label = "frequency (Hz)";
  SvgPanel poles;
  poles.y_label = "model order (pole pairs)";
  SvgSeries stable{"stable in f and zeta", {}, {}, "#1f77b4", true};
  SvgSeries other{"new or moving", {}, {}, "#bbbbbb", true};
  SvgSeries chosen{"selected model (after ML)", {}, {}, "#d62728", true};
  for (const auto& row : fit.stabilization) {
    for (size_t k = 0; k < row.poles.size(); ++k) {
      if (row.poles[k].imag() == 0.0) continue;
      SvgSeries& s = row.stable[k] ? stable : other;
      s.x.push_back(std::abs(row.poles[k]) / (2 * M_PI));
      s.y.push_back(row.modes);
    }
  }
  for (const auto& m : fit.modes) {
    chosen.x.push_back(m.f_hz);
    chosen.y.push_back(fit.selected_modes);
  }
  poles.series = {other, stable, chosen};
  SvgPanel mag;
  mag.y_label = "mean |H|";
  mag.log_y = true;
  SvgSeries mean{"mean |H| over entries", {}, {}, "#333333"};
  for (size_t l = 0; l < frf.freq_hz.size(); ++l) {
    double s = 0.0;
    for (const auto& e : frf.entries) s += std::abs(e.h[l]);
    mean.x.push_back(frf.freq_hz[l]);
    mean.y.push_back(s / static_cast<double>(frf.entries.size()));
  }
  mag.series = {mean};
  fig.panels = {poles, mag};
  return render_svg(fig);
}

namespace {

// Phase in degrees, unwrapped along the lines: a compliance sits near
// +-180 deg above its modes, where wrapped values would jump across the
// whole panel with every noisy line.
std::vector<double> unwrapped_phase_deg(const std::vector<std::complex<double>>& h) {
  std::vector<double> out(h.size());
  double offset = 0.0, prev = 0.0;
  for (size_t k = 0; k < h.size(); ++k) {
    const double a = std::arg(h[k]);
    if (k > 0) {
      const double d = a - prev;
      if (d > M_PI) offset -= 2 * M_PI;
      if (d < -M_PI) offset += 2 * M_PI;
    }
    prev = a;
    out[k] = (a + offset) * 180.0 / M_PI;
  }
  return out;
}

}  // namespace

std::string bode_svg(const FrfData& measured, const FrfData& model, const std::string& title, int max_entries) {
  // The strongest entries carry the modes a reader looks for first.
  std::vector<std::pair<double, const FrfEntry*>> ranked;
  for (const auto& e : measured.entries) {
    double s = 0.0;
    for (const auto& h : e.h) s += std::norm(h);
    ranked.push_back({s, &e});
  }
  std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  if (static_cast<int>(ranked.size()) > max_entries) ranked.resize(static_cast<size_t>(std::max(0, max_entries)));
  static const char* kColors[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};
  SvgFigure fig;
  fig.title = title;
  fig.x_label = "frequency (Hz)";
  SvgPanel mag, phase;
  mag.y_label = "|H| (" + measured.unit + ")";
  mag.log_y = true;
  phase.y_label = "phase, unwrapped (deg)";
  for (size_t k = 0; k < ranked.size(); ++k) {
    const FrfEntry& e = *ranked[k].second;
    const std::string color = kColors[k % std::size(kColors)];
    const std::string name = e.output + "/" + e.input;
    SvgSeries m{name + " measured", measured.freq_hz, {}, color}, p{"", measured.freq_hz, unwrapped_phase_deg(e.h), color};
    for (const auto& h : e.h) m.y.push_back(std::abs(h));
    mag.series.push_back(m);
    phase.series.push_back(p);
    if (const FrfEntry* me = model.find(e.output, e.input)) {
      SvgSeries mm{name + " model", model.freq_hz, {}, color, false, true},
          mp{"", model.freq_hz, unwrapped_phase_deg(me->h), color, false, true};
      for (const auto& h : me->h) mm.y.push_back(std::abs(h));
      mag.series.push_back(mm);
      phase.series.push_back(mp);
    }
  }
  fig.panels = {mag, phase};
  return render_svg(fig);
}

}  // namespace ambdiag
