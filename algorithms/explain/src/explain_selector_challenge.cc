// The selection engine (explain_selector.h): the challengers of a
// selection: one physics instead of several (parsimony), other physics in a
// claim's place (alternatives), a resonant attachment the catalogue lacks.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>

#include <Eigen/Dense>

#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/core/error.h"
#include "explain_selector.h"

namespace ambdiag::detail {

std::optional<std::string> Selector::replace_by_single(std::vector<Selected>& sel, const std::vector<Candidate>& physics) {
  int claims = 0, p_sel = 0;
  for (const auto& s : sel) {
    if (!s.c.is_update) ++claims;
    p_sel += static_cast<int>(s.c.params.size());
  }
  if (sel.size() < 2 || claims < 1) return std::nullopt;
  const PlantVariant cur = build(sel);
  const double cfs = chi2(cur, fit_), cvs = chi2(cur, val_);
  const std::optional<Trial> t = step({}, {}, physics, false);
  if (!t) return std::nullopt;
  const double p1 = static_cast<double>(t->c->params.size());
  const double pen = penalty_per_param_;
  progress("parsimony: " + t->c->id + fmt(" alone: chi2 fit %.6g val %.6g; ", t->chi2_fit, t->chi2_val) +
           fmt("the %.0f pieces selected: %.6g / ", static_cast<double>(sel.size()), cfs) + fmt("%.6g", cvs));
  if (t->chi2_fit + pen * p1 > cfs + pen * p_sel || t->chi2_val + pen * p1 > cvs + pen * p_sel) return std::nullopt;
  Selected one;
  one.c = *t->c;
  one.x = t->x;
  one.report.physics = t->c->physics;
  one.report.chi2_drop_fit = t->gain_fit;
  one.report.chi2_drop_validation = t->gain_val;
  one.report.penalty = t->threshold_val;
  progress(fmt("replaced %.0f pieces by one: ", static_cast<double>(sel.size())) + t->c->id);
  sel.clear();
  sel.push_back(std::move(one));
  refit_all(sel);
  prune(sel);
  return t->c->id;
}

std::vector<Selector::Alternative> Selector::alternatives(const std::vector<Selected>& sel, const std::vector<Candidate>& physics) {
  constexpr double kDecisive = 2.0 * 4.605170185988092;  // 2 ln 100
  std::vector<Alternative> out;
  const PlantVariant cur = build(sel);
  const double cfs = chi2(cur, fit_), cvs = chi2(cur, val_);
  for (size_t k = 0; k < sel.size(); ++k) {
    if (sel[k].c.is_update) continue;
    std::vector<Selected> others = sel;
    others.erase(others.begin() + static_cast<long>(k));
    std::vector<Candidate> pool;
    for (const auto& c : physics)
      if (c.physics != sel[k].c.physics && c.physics != "parameter_update") pool.push_back(c);
    const std::optional<Trial> t = step(others, {}, pool, false);
    if (!t) continue;
    const double df = t->chi2_fit - cfs, dv = t->chi2_val - cvs;
    progress("alternative to " + sel[k].c.id + ": " + t->c->id + fmt(" chi2 %+.4g (fit), %+.4g (held-out)", df, dv));
    if (df > kDecisive && dv > kDecisive) continue;
    out.push_back({sel[k].c.id, *t->c, t->x, df, dv});
  }
  return out;
}

std::optional<Selector::Attachment> Selector::attachment_challenge(std::vector<Selected>& sel) {
  int sel_params = 0;
  for (const auto& s : sel) sel_params += static_cast<int>(s.c.params.size());
  const PlantVariant base = build({});
  const auto r0 = residual(base, fit_), rv0 = residual(base, val_);
  const double cf0 = chi2_of(r0), cv0 = chi2_of(rv0);
  const PlantVariant full = build(sel);
  const double cfs = chi2(full, fit_), cvs = chi2(full, val_);
  const std::vector<double>& f = eval_.measured().freq_hz;
  // One piece of at most 3 parameters that fits to the noise cannot be
  // beaten by 3 parameters: no challenge (it costs about a second).
  const double n_fit = static_cast<double>(r0.size());
  if (sel.size() == 1 && sel_params <= 3 && cfs <= n_fit + 5.0 * std::sqrt(n_fit)) return std::nullopt;
  // Worth a look only where the updates leave more than the noise.
  if (cf0 - static_cast<double>(r0.size()) < threshold(3, cf0)) return std::nullopt;
  detail::RotorScreen scr(base, eval_);
  const auto rs0 = residual(base, screen_lines_);
  std::optional<Attachment> best;
  const int nodes = nominal_.node_count();
  struct Start {
    double chi2;
    Candidate c;
    detail::LowRankChange ch;
    std::vector<double> x;
  };
  std::vector<Start> starts;
  // The grid runs on every fourth screen line (the peak of a resonance
  // spans several lines), the short fits on all screen lines.
  std::vector<int> coarse_lines;
  for (size_t k = 0; k < screen_lines_.size(); k += 4) coarse_lines.push_back(screen_lines_[k]);
  const auto rc0 = residual(base, coarse_lines);
  const double mr = nominal_.rotor_mass_kg();
  for (int n = 0; n < nodes; ++n) {
    Candidate c = resonant_attachment(nominal_, n, f.front(), f.back());
    const std::optional<detail::LowRankChange> ch = scr.change_of(c);
    if (!ch) continue;
    auto resid_on = [&](const std::vector<double>& x, const std::vector<int>& lines, const std::vector<std::complex<double>>& r_base) {
      return scr.residual_with(*ch, c, x, lines, r_base);
    };
    // A grid first: 150 frequencies (geometric over the band, 4.7 % apart
    // over three decades) x 4 damping ratios (0.5-4 %) x 4 masses (1-8 %
    // of the rotor): the resonance of a lightly damped part is narrow, and
    // a fit from a start far from it does not find it. The best point of
    // each of 9 frequency bins (a third of a decade each over 1-1000 Hz)
    // is kept: the quasi-static mass effect below any tuning makes low
    // frequencies look good on the grid, the resonance shows only near it.
    constexpr int kBins = 9;
    std::vector<std::pair<double, std::vector<double>>> bin_best(kBins, {std::numeric_limits<double>::infinity(), {}});
    constexpr int kFrequencies = 150;
    for (int g = 0; g < kFrequencies; ++g) {
      std::vector<double> x = neutral(c);
      const double t = (g + 0.5) / kFrequencies;
      x[0] = f.front() * std::pow(f.back() / f.front(), t);
      auto& slot = bin_best[static_cast<size_t>(std::min(kBins - 1, static_cast<int>(t * kBins)))];
      for (double zeta : {0.005, 0.01, 0.02, 0.04})
        for (double share : {0.01, 0.02, 0.04, 0.08}) {
          x[1] = zeta;
          x[2] = share * mr;
          const double v = chi2_of(resid_on(x, coarse_lines, rc0));
          if (v < slot.first) slot = {v, x};
        }
    }
    std::vector<std::vector<double>> picks;
    for (const auto& slot : bin_best)
      if (!slot.second.empty()) picks.push_back(slot.second);
    // A short fit on the screen lines from each ranks the node at its optimum.
    Start st{std::numeric_limits<double>::infinity(), c, *ch, {}};
    for (const auto& x0 : picks) {
      std::vector<FitParameter> params = c.params;
      for (size_t i = 0; i < params.size(); ++i) params[i].initial = x0[i];
      LeastSquaresOptions o;
      o.max_iterations = 10;
      o.rel_tolerance = 1e-4;
      const LeastSquaresResult fr =
          fit_least_squares([&](const std::vector<double>& x) { return resid_on(x, screen_lines_, rs0); }, params, o);
      if (fr.chi2 < st.chi2) st.chi2 = fr.chi2, st.x = fr.x;
    }
    if (!st.x.empty()) starts.push_back(std::move(st));
  }
  std::sort(starts.begin(), starts.end(), [](const Start& a, const Start& b) { return a.chi2 < b.chi2; });
  if (starts.size() > 3) starts.resize(3);
  for (const auto& st : starts) {
    const Candidate& c = st.c;
    auto resid = [&](const std::vector<double>& x, const std::vector<int>& lines, const std::vector<std::complex<double>>& base_r) {
      return scr.residual_with(st.ch, c, x, lines, base_r);
    };
    std::vector<FitParameter> params = c.params;
    for (size_t i = 0; i < params.size(); ++i) params[i].initial = st.x[i];
    LeastSquaresOptions o;
    o.max_iterations = 30;
    o.rel_tolerance = 1e-6;
    const LeastSquaresResult fr = fit_least_squares([&](const std::vector<double>& x) { return resid(x, fit_, r0); }, params, o);
    Attachment a{c, fr.x, fr.chi2, chi2_of(resid(fr.x, val_, rv0))};
    if (!best || a.chi2_fit + a.chi2_val < best->chi2_fit + best->chi2_val) best = std::move(a);
  }
  if (!best) return std::nullopt;
  bool on_bound = false;
  for (size_t i = 0; i < best->c.params.size(); ++i) on_bound = on_bound || on_foreign_bound(best->c.params[i], best->x[i]);
  const double pen_a = 3.0 * penalty_per_param_, pen_s = sel_params * penalty_per_param_;
  const bool beats = best->chi2_fit + pen_a <= cfs + pen_s && best->chi2_val + pen_a <= cvs + pen_s;
  progress("attachment challenger: " + best->c.id + " " + best->c.describe(best->x).dump() +
           fmt(": chi2 fit %.6g val %.6g against the physics' %.6g / ", best->chi2_fit, best->chi2_val, cfs) + fmt("%.6g", cvs) +
           (on_bound ? " (on a bound)" : ""));
  if (on_bound || (!beats && !sel.empty())) return std::nullopt;
  if (!sel.empty()) {
    progress("the selection gives way: one resonant attachment, which the plant format cannot express, fits as well");
    sel.clear();
  } else if (best->chi2_fit + pen_a > cf0 || best->chi2_val + pen_a > cv0) {
    return std::nullopt;  // with no claims to replace, it must at least pay for itself
  }
  return best;
}

}  // namespace ambdiag::detail
