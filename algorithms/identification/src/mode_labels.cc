#include "ambdiag/algorithms/identification/mode_labels.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <map>
#include <tuple>

namespace ambdiag {

namespace {

struct Axis {
  std::string plane;
  char dir = '?';
};

Axis axis_of(const std::string& name, bool sensor, const PlantModel* plant) {
  if (plant) {
    const MeasurementPoint* p = sensor ? plant->find_sensor(name) : plant->find_actuator(name);
    if (p) return {p->plane, p->dir};
  }
  if (name.empty()) return {};
  const char last = static_cast<char>(std::tolower(static_cast<unsigned char>(name.back())));
  // "xAx" -> plane "A" (the characters between a leading letter and the axis letter).
  std::string plane = name.size() > 2 ? name.substr(1, name.size() - 2) : "";
  return {plane, (last == 'x' || last == 'y' || last == 'z') ? last : '?'};
}

}  // namespace

ModeDescription describe_mode(const IdentifiedMode& mode, const RationalFitResult& fit, const FrfData& frf,
                              const PlantModel* plant) {
  ModeDescription d;
  d.mode = mode;
  const size_t n = fit.entries.size();
  double axial = 0.0, total = 0.0, strongest = 0.0;
  for (size_t e = 0; e < n; ++e) strongest = std::max(strongest, mode.entry_weight[e]);
  std::map<std::string, double> out_share, in_share;
  // (plane, input) -> residues of the x and y sensors of that plane.
  std::map<std::pair<std::string, std::string>, std::pair<std::complex<double>, std::complex<double>>> xy;
  for (size_t e = 0; e < n; ++e) {
    const FrfEntry& en = frf.entries[static_cast<size_t>(fit.entries[e])];
    const Axis so = axis_of(en.output, true, plant), ai = axis_of(en.input, false, plant);
    const double w = mode.entry_weight[e];
    total += w;
    if (so.dir == 'z' && ai.dir == 'z') axial += w;
    if (w >= 0.05 * strongest) {
      out_share[en.output] += w;
      in_share[en.input] += w;
    }
    const std::complex<double> r = fit.model.residues(static_cast<Eigen::Index>(e), mode.pole_index);
    if (so.dir == 'x') xy[{so.plane, en.input}].first = r;
    if (so.dir == 'y') xy[{so.plane, en.input}].second = r;
  }
  d.direction = total > 0 && axial > 0.5 * total ? "axial" : "radial";
  for (const auto& [name, share] : out_share) d.outputs.push_back(name);
  for (const auto& [name, share] : in_share) d.inputs.push_back(name);
  if (d.direction == "radial") {
    double s = 0.0, norm = 0.0;
    for (const auto& [key, r] : xy) {
      s += std::imag(std::conj(r.first) * r.second);
      norm += std::abs(r.first) * std::abs(r.second);
    }
    // Require a clear circular component; nearly linear orbits stay "none".
    if (norm > 0 && std::abs(s) > 0.3 * norm) d.whirl = s < 0 ? Whirl::forward : Whirl::backward;
  }
  return d;
}

ModePairing pair_with_model(std::vector<ModeDescription> identified, const std::vector<Mode>& model_modes,
                            double f_min_hz, double f_max_hz, double max_rel_distance) {
  ModePairing out;
  std::vector<int> model_in_band;
  for (size_t m = 0; m < model_modes.size(); ++m) {
    const Mode& mm = model_modes[m];
    if (mm.f_hz <= 0.0 || mm.overdamped || mm.f_hz < f_min_hz || mm.f_hz > f_max_hz) continue;
    model_in_band.push_back(static_cast<int>(m));
  }
  // Candidate pairs, closest first.
  std::vector<std::tuple<double, int, int>> cand;
  for (size_t i = 0; i < identified.size(); ++i) {
    for (int m : model_in_band) {
      const Mode& mm = model_modes[static_cast<size_t>(m)];
      const ModeDescription& id = identified[i];
      if (mm.direction != id.direction) continue;
      if (id.whirl != Whirl::none && mm.whirl != Whirl::none && id.whirl != mm.whirl) continue;
      const double rel = std::abs(id.mode.f_hz - mm.f_hz) / mm.f_hz;
      if (rel <= max_rel_distance) cand.emplace_back(rel + 0.1 * std::abs(id.mode.zeta - mm.zeta), static_cast<int>(i), m);
    }
  }
  std::sort(cand.begin(), cand.end());
  std::vector<bool> used_model(model_modes.size(), false);
  for (const auto& [score, i, m] : cand) {
    ModeDescription& id = identified[static_cast<size_t>(i)];
    if (id.model_index >= 0 || used_model[static_cast<size_t>(m)]) continue;
    id.model_index = m;
    used_model[static_cast<size_t>(m)] = true;
    const Mode& mm = model_modes[static_cast<size_t>(m)];
    id.label = mm.label.empty() ? mm.kind : mm.label;
    if (mm.whirl != Whirl::none) id.label += " (" + to_string(mm.whirl) + ")";
  }
  for (int m : model_in_band)
    if (!used_model[static_cast<size_t>(m)]) out.unmatched_model.push_back(m);
  for (size_t i = 0; i < identified.size(); ++i)
    if (identified[i].model_index < 0) out.unmatched_identified.push_back(static_cast<int>(i));
  out.identified = std::move(identified);
  return out;
}

}  // namespace ambdiag
