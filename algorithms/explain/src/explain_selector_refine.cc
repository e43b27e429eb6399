// The selection engine (explain_selector.h): refitting a selection,
// folding updates, refining discrete locations, merging and pruning pieces.
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

void Selector::refit_all(std::vector<Selected>& sel, int max_iterations) {
  std::vector<FitParameter> params;
  std::vector<size_t> offset;
  for (const auto& s : sel) {
    offset.push_back(params.size());
    for (size_t i = 0; i < s.c.params.size(); ++i) {
      FitParameter p = s.c.params[i];
      p.initial = s.x[i];
      params.push_back(p);
    }
  }
  if (params.empty()) return;
  auto unpack = [&](const std::vector<double>& x) {
    std::vector<Selected> s2 = sel;
    for (size_t k = 0; k < s2.size(); ++k)
      for (size_t i = 0; i < s2[k].x.size(); ++i) s2[k].x[i] = x[offset[k] + i];
    return s2;
  };
  LeastSquaresOptions fo;
  fo.max_iterations = max_iterations;
  const LeastSquaresResult fr = fit_least_squares([&](const std::vector<double>& x) { return residual(build(unpack(x)), fit_); }, params, fo);
  evaluations_ += fr.evaluations;
  sel = unpack(fr.x);
  for (size_t k = 0; k < sel.size(); ++k) {
    nlohmann::json sd = nlohmann::json::object();
    for (size_t i = 0; i < sel[k].c.params.size(); ++i)
      if (std::isfinite(fr.sd[offset[k] + i])) sd[sel[k].c.params[i].name] = fr.sd[offset[k] + i];
    sel[k].report.sd = sd;
  }
}

void Selector::fold_updates(std::vector<Selected>& sel) {
  for (size_t a = 0; a < sel.size(); ++a) {
    for (size_t b = 0; b < sel.size(); ++b) {
      if (a == b || !sel[a].c.is_update || sel[b].c.is_update || sel[a].c.direction_key.empty() ||
          sel[a].c.direction_key != sel[b].c.direction_key || sel[a].x.size() != 1 || sel[b].x.size() != 1)
        continue;
      sel[b].x[0] = std::clamp(sel[b].x[0] * sel[a].x[0], sel[b].c.params[0].lower, sel[b].c.params[0].upper);
      progress("folded " + sel[a].c.id + " into " + sel[b].c.id);
      sel.erase(sel.begin() + static_cast<long>(a));
      return fold_updates(sel);
    }
  }
}

void Selector::refine_locations(std::vector<Selected>& sel) {
  merge_between(sel);
  std::set<std::string> visited;  // a piece never moves back to where it was (moves could oscillate)
  for (const auto& s : sel) visited.insert(s.c.id);
  for (int round = 0; round < 4; ++round) {
    bool moved = false;
    for (size_t k = 0; k < sel.size(); ++k) {
      for (const Candidate& alt : neighbour_candidates(nominal_, sel[k].c)) {
        if (visited.count(alt.id)) continue;
        const PlantVariant cur = build(sel);
        const double cf = chi2(cur, fit_), cv = chi2(cur, val_);
        std::vector<Selected> others = sel;
        others.erase(others.begin() + static_cast<long>(k));
        const Trial t = try_candidate(others, alt, nullptr, cf, cv, &sel[k].x);
        if (t.chi2_fit < cf && t.chi2_val < cv) {
          progress("moved " + sel[k].c.id + " to " + alt.id);
          visited.insert(alt.id);
          sel[k].c = alt;
          sel[k].x = t.x;
          moved = true;
          break;
        }
      }
    }
    // Two of the same physics at one place are one: add their parameters.
    for (size_t a = 0; a < sel.size(); ++a) {
      for (size_t b = a + 1; b < sel.size(); ++b) {
        if (sel[a].c.id != sel[b].c.id || sel[a].c.physics != "added_mass") continue;
        for (size_t i = 0; i < sel[a].x.size(); ++i) sel[a].x[i] += sel[b].x[i];
        progress("merged two " + sel[a].c.id);
        sel.erase(sel.begin() + static_cast<long>(b));
        moved = true;
        break;
      }
    }
    if (!moved) break;
    refit_all(sel);
  }
}

void Selector::merge_between(std::vector<Selected>& sel) {
  for (size_t a = 0; a < sel.size(); ++a) {
    for (size_t b = a + 1; b < sel.size(); ++b) {
      if (sel[a].c.physics != "added_mass" || sel[b].c.physics != "added_mass") continue;
      const int na = sel[a].c.location["node"].get<int>(), nb = sel[b].c.location["node"].get<int>();
      const PlantVariant cur = build(sel);
      const double cf = chi2(cur, fit_), cv = chi2(cur, val_);
      std::vector<Selected> others = sel;
      others.erase(others.begin() + static_cast<long>(b));
      others.erase(others.begin() + static_cast<long>(a));
      std::vector<double> sum = sel[a].x;
      for (size_t i = 0; i < sum.size(); ++i) sum[i] += sel[b].x[i];
      std::optional<Trial> best;
      Candidate best_c;
      for (int n = std::min(na, nb); n <= std::max(na, nb); ++n) {
        Candidate c = sel[a].c;
        for (const Candidate& alt : neighbour_candidates(nominal_, c))
          if (alt.location["node"].get<int>() == n) c = alt;
        if (c.location["node"].get<int>() != n) {  // not a neighbour of a: build from b's neighbours or a itself
          for (const Candidate& alt : neighbour_candidates(nominal_, sel[b].c))
            if (alt.location["node"].get<int>() == n) c = alt;
        }
        if (c.location["node"].get<int>() != n) continue;
        Trial t = try_candidate(others, c, nullptr, cf, cv, &sum);
        if (!best || t.chi2_fit < best->chi2_fit) {
          best = t;
          best_c = c;
        }
      }
      if (best) {
        Selected m = sel[a];
        m.c = best_c;
        m.x = best->x;
        std::vector<Selected> merged = others;
        merged.push_back(m);
        refit_all(merged);
        const PlantVariant mv = build(merged);
        if (chi2(mv, fit_) >= cf || chi2(mv, val_) >= cv) continue;
        progress("merged " + sel[a].c.id + " and " + sel[b].c.id + " into " + best_c.id);
        sel = merged;
        return merge_between(sel);
      }
    }
  }
}

void Selector::prune(std::vector<Selected>& sel) {
  constexpr double kSignificantSd = 3.0;
  for (size_t k = 0; k < sel.size();) {
    bool pinned = false;
    for (size_t i = 0; i < sel[k].c.params.size() && !sel[k].c.is_update; ++i) pinned = pinned || on_foreign_bound(sel[k].c.params[i], sel[k].x[i]);
    if (pinned) {
      progress("dropped " + sel[k].c.id + " (a parameter ends on its bound: not a plausible explanation)");
      sel.erase(sel.begin() + static_cast<long>(k));
      continue;
    }
    bool significant = !sel[k].c.is_update || sel[k].c.params.empty();
    for (size_t i = 0; i < sel[k].c.params.size() && !significant; ++i) {
      const auto& fp = sel[k].c.params[i];
      const double change = std::abs(sel[k].x[i] - fp.initial);
      const auto it = sel[k].report.sd.find(fp.name);
      // No sd (at a bound or not refitted): judged by the chi2 rule alone.
      significant = it == sel[k].report.sd.end() || change > kSignificantSd * it->get<double>();
    }
    if (significant) {
      ++k;
      continue;
    }
    progress("dropped " + sel[k].c.id + " (change within " + fmt("%.0f", kSignificantSd) + " sd of the nominal value)");
    sel.erase(sel.begin() + static_cast<long>(k));
  }
  bool dropped = true;
  while (dropped && !sel.empty()) {
    dropped = false;
    const PlantVariant cur = build(sel);
    const double cf = chi2(cur, fit_), cv = chi2(cur, val_);
    for (size_t k = 0; k < sel.size(); ++k) {
      std::vector<Selected> without = sel;
      without.erase(without.begin() + static_cast<long>(k));
      const PlantVariant v = build(without);
      const double loss_f = chi2(v, fit_) - cf, loss_v = chi2(v, val_) - cv;
      const int p = static_cast<int>(sel[k].c.params.size());
      if (loss_f < threshold(p, cf) || loss_v < threshold(p, cv)) {
        progress("dropped " + sel[k].c.id + " (no longer pays once the others are fitted)");
        sel.erase(sel.begin() + static_cast<long>(k));
        dropped = true;
        break;
      }
    }
  }
}

}  // namespace ambdiag::detail
