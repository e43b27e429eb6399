// Campbell diagram as an SVG figure and as JSON.
#include <array>
#include <cmath>

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/model/campbell.h"
#include "ambdiag/core/svg_plot.h"

namespace ambdiag {

namespace {

constexpr std::array<const char*, 8> kFamilyColors = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e",
                                                      "#9467bd", "#8c564b", "#e377c2", "#17becf"};

nlohmann::json number_or_null(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

nlohmann::json numbers(const std::vector<double>& v) {
  nlohmann::json a = nlohmann::json::array();
  for (double x : v) a.push_back(number_or_null(x));
  return a;
}

nlohmann::json optional_number(const std::optional<double>& v) {
  return v ? number_or_null(*v) : nlohmann::json(nullptr);
}

}  // namespace

std::string campbell_svg(const CampbellResult& r, const std::string& title) {
  SvgFigure fig;
  fig.title = title;
  fig.x_label = "speed (rpm)";
  fig.height_per_panel = 400;
  if (!r.speeds_rpm.empty()) fig.x_range = {{r.speeds_rpm.front(), r.speeds_rpm.back()}};
  if (fig.x_range && !(fig.x_range->second > fig.x_range->first)) fig.x_range.reset();

  SvgPanel freq, damp;
  freq.y_label = "frequency (Hz)";
  freq.y_range = {{0.0, r.f_max_hz}};
  damp.y_label = "log decrement (-)";
  // A track's colour follows its rank so that 1F and 1B match.
  int n_fwd = 0, n_bwd = 0, n_other = 0;
  for (const auto& t : r.tracks) {
    const int rank = t.whirl == Whirl::forward ? n_fwd++ : t.whirl == Whirl::backward ? n_bwd++ : n_other++;
    SvgSeries s;
    s.label = t.label;
    s.x = r.speeds_rpm;
    s.y = t.f_hz;
    s.color = kFamilyColors[static_cast<size_t>(rank) % kFamilyColors.size()];
    s.dashed = t.whirl == Whirl::backward;
    freq.series.push_back(s);
    s.label.clear();
    s.y = t.log_dec;
    damp.series.push_back(std::move(s));
  }
  for (const auto& m : r.fixed_modes) {
    // Axial modes do not belong on a lateral diagram.
    if (m.kind != "housing" || m.f_hz <= 0 || m.f_hz > r.f_max_hz || r.speeds_rpm.empty()) continue;
    SvgSeries s;
    s.label = m.label;
    s.x = {r.speeds_rpm.front(), r.speeds_rpm.back()};
    s.y = {m.f_hz, m.f_hz};
    s.color = "#aaaaaa";
    s.dashed = true;
    s.line_width_px = 1.0;
    freq.series.push_back(std::move(s));
  }
  if (!r.speeds_rpm.empty()) {
    const std::vector<double> ends = {r.speeds_rpm.front(), r.speeds_rpm.back()};
    SvgSeries one_x;
    one_x.label = "1x";
    one_x.x = ends;
    one_x.y = {ends[0] / 60.0, ends[1] / 60.0};
    one_x.color = "#555555";
    one_x.line_width_px = 1.0;
    freq.series.push_back(std::move(one_x));
    SvgSeries zero;
    zero.x = ends;
    zero.y = {0.0, 0.0};
    zero.color = "#555555";
    zero.line_width_px = 1.0;
    damp.series.push_back(std::move(zero));
  }
  if (!r.critical_speeds.empty()) {
    SvgSeries crit;
    crit.label = "critical speeds";
    crit.color = "black";
    crit.markers = true;
    for (const auto& c : r.critical_speeds) {
      crit.x.push_back(c.speed_rpm);
      crit.y.push_back(c.f_hz);
    }
    freq.series.push_back(std::move(crit));
  }
  fig.panels = {std::move(freq), std::move(damp)};
  return render_svg(fig);
}

nlohmann::json campbell_to_json(const CampbellResult& r) {
  using nlohmann::json;
  json tracks = json::array();
  for (const auto& t : r.tracks) {
    json whirl = json::array();
    for (Whirl w : t.whirl_at) whirl.push_back(w == Whirl::none ? json(nullptr) : json(to_string(w)));
    tracks.push_back({{"label", t.label},
                      {"whirl", to_string(t.whirl)},
                      {"f_hz", numbers(t.f_hz)},
                      {"zeta", numbers(t.zeta)},
                      {"log_dec", numbers(t.log_dec)},
                      {"whirl_at", std::move(whirl)},
                      {"mac", numbers(t.mac)},
                      {"min_log_dec", number_or_null(t.min_log_dec)},
                      {"min_log_dec_speed_rpm", number_or_null(t.min_log_dec_speed_rpm)},
                      {"instability_onset_rpm", optional_number(t.instability_onset_rpm)}});
  }
  json crit = json::array();
  for (const auto& c : r.critical_speeds) {
    crit.push_back({{"speed_rpm", c.speed_rpm},
                    {"f_hz", c.f_hz},
                    {"track", c.track},
                    {"label", c.label},
                    {"whirl", to_string(c.whirl)},
                    {"log_dec", number_or_null(c.log_dec)}});
  }
  json fixed = json::array();
  for (const auto& m : r.fixed_modes) {
    fixed.push_back({{"label", m.label}, {"kind", m.kind}, {"f_hz", m.f_hz}, {"zeta", m.zeta}});
  }
  return {{"speeds_rpm", numbers(r.speeds_rpm)},
          {"f_max_hz", r.f_max_hz},
          {"tracks", std::move(tracks)},
          {"critical_speeds", std::move(crit)},
          {"fixed_modes", std::move(fixed)},
          {"stable", r.stable},
          {"instability_onset_rpm", optional_number(r.instability_onset_rpm)},
          {"worst_mac", r.worst_mac}};
}

}  // namespace ambdiag
