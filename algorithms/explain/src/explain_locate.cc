// Step 1 of explain.h: where model and measurement differ beyond the noise,
// which entries, and what kind of difference.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "ambdiag/algorithms/explain/explain.h"
#include "explain_locate.h"

namespace ambdiag {

namespace {

constexpr int kWindow = 9;  // lines of the moving mean of |r|^2

struct Interval {
  size_t lo, hi;  // lines, inclusive
  size_t entry;
};

// Runs of lines where the centred moving mean of |r|^2 exceeds the threshold,
// widened by half a window and merged when closer than a window.
std::vector<std::pair<size_t, size_t>> flagged_runs(const std::vector<double>& e2, double threshold) {
  const size_t n = e2.size();
  std::vector<std::pair<size_t, size_t>> runs;
  if (n < static_cast<size_t>(kWindow)) return runs;
  const size_t h = kWindow / 2;
  std::vector<double> cum(n + 1, 0.0);
  for (size_t l = 0; l < n; ++l) cum[l + 1] = cum[l] + e2[l];
  for (size_t c = h; c + h < n; ++c) {
    const double mean = (cum[c + h + 1] - cum[c - h]) / kWindow;
    if (mean <= threshold) continue;
    const size_t lo = c - h, hi = c + h;
    if (!runs.empty() && lo <= runs.back().second + kWindow) runs.back().second = std::max(runs.back().second, hi);
    else runs.push_back({lo, hi});
  }
  return runs;
}

std::string entry_name(const FrfEntry& e) { return e.output + "/" + e.input; }

// Peak index of |h| within [lo, hi].
size_t argmax_abs(const std::vector<std::complex<double>>& h, size_t lo, size_t hi) {
  size_t best = lo;
  for (size_t l = lo; l <= hi; ++l)
    if (std::abs(h[l]) > std::abs(h[best])) best = l;
  return best;
}

bool interior_extremum(const std::vector<std::complex<double>>& h, size_t lo, size_t hi, bool maximum) {
  for (size_t l = std::max<size_t>(lo, 1); l + 1 <= hi && l + 1 < h.size(); ++l) {
    const double a = std::abs(h[l - 1]), b = std::abs(h[l]), c = std::abs(h[l + 1]);
    if (maximum ? (b > a && b > c) : (b < a && b < c)) return true;
  }
  return false;
}

}  // namespace

std::vector<Mismatch> locate_mismatches(const PlantModel& plant, const FrfData& model, const PlantFrfEvaluator& eval,
                                        const std::vector<Mode>& model_modes, double window_threshold) {
  const FrfData& meas = eval.measured();
  const size_t n = meas.freq_hz.size();
  std::vector<Interval> intervals;
  std::vector<std::vector<double>> e2(meas.entries.size(), std::vector<double>(n));
  for (size_t e = 0; e < meas.entries.size(); ++e) {
    const FrfEntry* mo = model.find(meas.entries[e].output, meas.entries[e].input);
    if (!mo) continue;
    for (size_t l = 0; l < n; ++l) e2[e][l] = std::norm((mo->h[l] - meas.entries[e].h[l]) / eval.sigma(e, l));
    for (auto [lo, hi] : flagged_runs(e2[e], window_threshold)) intervals.push_back({lo, hi, e});
  }
  std::sort(intervals.begin(), intervals.end(), [](const Interval& a, const Interval& b) { return a.lo < b.lo; });

  // Clusters of intervals that overlap in frequency.
  std::vector<std::vector<Interval>> clusters;
  size_t cluster_hi = 0;
  for (const auto& iv : intervals) {
    if (clusters.empty() || iv.lo > cluster_hi) clusters.push_back({});
    clusters.back().push_back(iv);
    cluster_hi = clusters.back().size() == 1 ? iv.hi : std::max(cluster_hi, iv.hi);
  }

  std::vector<Mismatch> out;
  for (const auto& cl : clusters) {
    Mismatch m;
    size_t lo = n, hi = 0;
    std::set<size_t> ents;
    for (const auto& iv : cl) {
      lo = std::min(lo, iv.lo);
      hi = std::max(hi, iv.hi);
      ents.insert(iv.entry);
    }
    m.band_lo_hz = meas.freq_hz[lo];
    m.band_hi_hz = meas.freq_hz[hi];
    std::set<std::string> outs, ins, planes, dirs, axes;
    int direct = 0, cross = 0;
    double sum = 0.0, cross_energy = 0.0, total_energy = 0.0;
    // Share of the band's weighted residual that one delay explains:
    // d ~ tau a with a = -j w H_model / sigma (least squares in tau).
    double s_ad = 0.0, s_aa = 0.0, s_dd = 0.0;
    size_t worst = *ents.begin();
    double worst_e = -1.0;
    for (size_t e : ents) {
      const FrfEntry& me = meas.entries[e];
      const FrfEntry* mo = model.find(me.output, me.input);
      outs.insert(me.output);
      ins.insert(me.input);
      m.entries.push_back(entry_name(me));
      const MeasurementPoint* s = plant.find_sensor(me.output);
      const MeasurementPoint* a = plant.find_actuator(me.input);
      const bool is_cross = s && a && s->dir != a->dir;
      if (s && a) {
        planes.insert(s->plane);
        planes.insert(a->plane);
        dirs.insert(std::string(1, s->dir));
        dirs.insert(std::string(1, a->dir));
        axes.insert(s->is_axial() && a->is_axial() ? "axial" : (s->is_axial() || a->is_axial() ? "lateral-axial" : "radial"));
      }
      (is_cross ? cross : direct) += 1;
      double ee = 0.0;
      for (size_t l = lo; l <= hi; ++l) {
        ee += e2[e][l];
        const double sg = eval.sigma(e, l);
        const std::complex<double> da = std::complex<double>(0.0, -2 * M_PI * meas.freq_hz[l]) * mo->h[l] / sg;
        const std::complex<double> d = (me.h[l] - mo->h[l]) / sg;
        s_ad += (std::conj(da) * d).real();
        s_aa += std::norm(da);
        s_dd += std::norm(d);
      }
      sum += ee;
      total_energy += ee;
      if (is_cross) cross_energy += ee;
      if (ee > worst_e) {
        worst_e = ee;
        worst = e;
      }
    }
    m.outputs.assign(outs.begin(), outs.end());
    m.inputs.assign(ins.begin(), ins.end());
    m.chi2_per_line = sum / static_cast<double>(ents.size() * (hi - lo + 1));
    m.classification = {{"planes", std::vector<std::string>(planes.begin(), planes.end())},
                        {"directions", std::vector<std::string>(dirs.begin(), dirs.end())},
                        {"axes", std::vector<std::string>(axes.begin(), axes.end())},
                        {"direct_entries", direct},
                        {"cross_entries", cross}};

    // The rotor or housing mode of the model nearest the band's worst peak.
    const FrfEntry& me = meas.entries[worst];
    const FrfEntry* mo = model.find(me.output, me.input);
    const Mode* near = nullptr;
    for (const auto& md : model_modes) {
      if (md.overdamped || md.zeta > 0.5) continue;
      if (md.f_hz < m.band_lo_hz - 0.02 * md.f_hz || md.f_hz > m.band_hi_hz + 0.02 * md.f_hz) continue;
      const double mid = 0.5 * (m.band_lo_hz + m.band_hi_hz);
      if (!near || std::abs(md.f_hz - mid) < std::abs(near->f_hz - mid)) near = &md;
    }
    const double delay_share = s_aa > 0 && s_dd > 0 ? s_ad * s_ad / (s_aa * s_dd) : 0.0;
    if (delay_share > 0.7 && ents.size() >= 2) {
      m.kind = "phase_drift";
    } else if (cross > 0 && cross_energy > 0.6 * total_energy) {
      m.kind = "cross_asymmetry";
    } else if (near) {
      const size_t pm = argmax_abs(me.h, lo, hi), pd = argmax_abs(mo->h, lo, hi);
      const double df = std::abs(meas.freq_hz[pm] - meas.freq_hz[pd]);
      const double ratio = std::abs(me.h[pm]) / std::max(std::abs(mo->h[pd]), 1e-300);
      if (df > std::max(0.003 * meas.freq_hz[pm], 1.5 * (meas.freq_hz[std::min(lo + 1, n - 1)] - meas.freq_hz[lo])))
        m.kind = "shifted_resonance";
      else if (std::abs(std::log(ratio)) > 0.05)
        m.kind = "damping_change";
      else
        m.kind = "level_change";
    } else if (interior_extremum(me.h, lo, hi, true) && !interior_extremum(mo->h, lo, hi, true)) {
      m.kind = "extra_resonance";
    } else if (interior_extremum(mo->h, lo, hi, false) || interior_extremum(me.h, lo, hi, false)) {
      m.kind = "anti_resonance_moved";
    } else {
      m.kind = "level_change";
    }
    if (near) {
      m.mode = nlohmann::json{{"label", near->label.empty() ? near->kind : near->label},
                              {"f_hz", near->f_hz},
                              {"zeta", near->zeta},
                              {"direction", near->direction},
                              {"whirl", to_string(near->whirl)}};
    }
    out.push_back(std::move(m));
  }
  return out;
}

namespace detail {

std::vector<Mode> modes_in_band(const PlantModel& p, double rpm, double fmax) {
  ModalOptions mo;
  mo.shapes = true;
  mo.f_max_hz = fmax;
  std::vector<Mode> out;
  for (auto& m : modal_analysis(p, rpm, mo).modes)
    if (m.f_hz <= fmax) out.push_back(m);
  return out;
}

}  // namespace detail

}  // namespace ambdiag
