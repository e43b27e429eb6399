// Steps 2 and 3 of explain.h: greedy selection of parameter updates, then
// of missing physics, checked on held-out lines; the improved model and the
// figures before and after.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <functional>
#include <set>

#include <Eigen/Dense>

#include "ambdiag/algorithms/explain/explain.h"
#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/core/error.h"
#include "explain_locate.h"
#include "explain_selector.h"
#include "explain_speeds.h"

namespace ambdiag {

namespace {

using detail::fmt;
using detail::Selected;
using detail::Selector;

double nrmse_of(const FrfData& model, const FrfData& measured) { return compare_frf(model, measured).nrmse; }

std::vector<ModePair> pair_modes(const std::vector<Mode>& before, const std::vector<Mode>& after) {
  std::vector<ModePair> out;
  std::vector<bool> used(after.size(), false);
  auto usable = [](const Mode& m) { return !m.overdamped; };
  for (const auto& b : before) {
    if (!usable(b)) continue;
    int best = -1;
    double bd = 0.15;
    for (size_t k = 0; k < after.size(); ++k) {
      const Mode& a = after[k];
      if (used[k] || !usable(a) || a.direction != b.direction || a.kind != b.kind || a.whirl != b.whirl) continue;
      const double d = std::abs(a.f_hz - b.f_hz) / b.f_hz;
      if (d < bd) {
        bd = d;
        best = static_cast<int>(k);
      }
    }
    ModePair p;
    p.label = b.label.empty() ? b.kind : b.label;
    p.model_f_hz = b.f_hz;
    p.model_zeta = b.zeta;
    p.direction = b.direction;
    p.whirl = to_string(b.whirl);
    if (best < 0) {
      p.improved_f_hz = p.improved_zeta = std::numeric_limits<double>::quiet_NaN();
      p.status = "missing";
    } else {
      used[static_cast<size_t>(best)] = true;
      const Mode& a = after[static_cast<size_t>(best)];
      p.improved_f_hz = a.f_hz;
      p.improved_zeta = a.zeta;
      const bool shifted = std::abs(a.f_hz - b.f_hz) > 0.005 * b.f_hz;
      const bool damped = std::abs(a.zeta - b.zeta) > 0.1 * b.zeta;
      p.status = shifted ? "shifted" : damped ? "damping_changed" : "paired";
    }
    out.push_back(p);
  }
  for (size_t k = 0; k < after.size(); ++k) {
    if (used[k] || !usable(after[k])) continue;
    const Mode& a = after[k];
    out.push_back({a.label.empty() ? a.kind : a.label, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(),
                   a.f_hz, a.zeta, "extra", a.direction, to_string(a.whirl)});
  }
  std::sort(out.begin(), out.end(), [](const ModePair& x, const ModePair& y) {
    const double fx = std::isfinite(x.model_f_hz) ? x.model_f_hz : x.improved_f_hz;
    const double fy = std::isfinite(y.model_f_hz) ? y.model_f_hz : y.improved_f_hz;
    return fx < fy;
  });
  return out;
}


// How far going from model FRF `a` to `b` raised the NRMSE's numerator
// sum |H_model - H_measured|^2, in standard deviations of what the
// recording's noise alone does to it for that change: with complex Gaussian
// noise of std sigma per value the numerator moves by 2 Re sum conj(b - a)
// n, of variance 2 sum sigma^2 |b - a|^2. Negative: it fell.
double rise_in_noise_sd(const FrfData& a, const FrfData& b, const FrfData& measured, const PlantFrfEvaluator& eval) {
  double rise = 0.0, var = 0.0;
  for (size_t e = 0; e < measured.entries.size(); ++e)
    for (size_t l = 0; l < measured.freq_hz.size(); ++l) {
      const auto h = measured.entries[e].h[l];
      rise += std::norm(b.entries[e].h[l] - h) - std::norm(a.entries[e].h[l] - h);
      var += 2.0 * eval.sigma(e, l) * eval.sigma(e, l) * std::norm(b.entries[e].h[l] - a.entries[e].h[l]);
    }
  return var > 0.0 ? rise / std::sqrt(var) : (rise > 0.0 ? std::numeric_limits<double>::infinity() : 0.0);
}

}  // namespace

ExplainResult explain(const PlantModel& nominal, const FrfData& measured, const ExplainOptions& options) {
  return explain(nominal, measured, {}, options);
}

ExplainResult explain(const PlantModel& nominal, const FrfData& measured, const std::vector<FrfData>& other_speeds,
                      const ExplainOptions& options) {
  PlantFrfEvaluator eval(measured);
  Selector sel_engine(nominal, eval, options);
  ExplainResult res;
  const double rpm = eval.speed_rpm(nominal);
  detail::OtherSpeeds others(other_speeds, rpm);  // refuses bad recordings before any work
  const double fmax = measured.freq_hz.back();
  auto progress = [&](const std::string& s) {
    if (options.progress) options.progress(s);
  };

  // 1. Locate.
  const PlantVariant base{nominal, 0.0};
  res.model_before = eval.model_frf(base);
  const std::vector<Mode> modes_before = detail::modes_in_band(nominal, rpm, fmax);
  res.mismatches = locate_mismatches(nominal, res.model_before, eval, modes_before, options.window_threshold);
  progress("located " + std::to_string(res.mismatches.size()) + " mismatch band(s)");

  // 2. Select: updates and physics in one greedy loop, updates preferred.
  // The physics candidates are proposed from the residual of a variant.
  auto view_of = [&](const PlantVariant& v) {
    ResidualView view;
    view.measured = &eval.measured();
    view.model_h = eval.model_h(v, sel_engine.all_lines());
    for (size_t e = 0; e < measured.entries.size(); ++e) {
      std::vector<double> s(measured.freq_hz.size());
      for (size_t l = 0; l < s.size(); ++l) s[l] = eval.sigma(e, l);
      view.sigma.push_back(std::move(s));
    }
    return view;
  };
  std::vector<Selected> sel;
  const std::vector<Candidate> updates = update_candidates(nominal);
  // A step is chosen on chi2, which weighs each line by 1 / sigma^2; the
  // NRMSE it reports does not weigh (cli.md). On a run's FRF estimate sigma
  // is ~5 % of |H| at the rigid-body lines, where |H| and so the NRMSE are
  // largest, and ~0.3 % around the bending modes, where chi2 is: a piece can
  // buy chi2 there with a worse fit below (docs/explain.md, "Guarantee").
  // A step that raises the NRMSE by more than the noise explains (3 sd, see
  // rise_in_noise_sd) is refused for the rest of the selection and the step
  // tried again without it, up to kRefusals times in a row. (Within the
  // noise a step that chi2 finds significant stays: near the noise floor
  // the NRMSE's sign is noise; the report's chain below holds the reported
  // figures to strictly falling.)
  constexpr int kRefusals = 4;
  constexpr double kNoiseSd = 3.0;
  std::set<std::string> refused;
  int refusals = 0;
  for (int steps = 0; !res.mismatches.empty() && steps < options.max_steps; ++steps) {
    const std::vector<Candidate> physics = physics_candidates(nominal, view_of(sel_engine.build(sel)));
    const FrfData model_now = eval.model_frf(sel_engine.build(sel));
    const double nrmse_before = nrmse_of(model_now, measured);
    auto t = sel_engine.step(sel, updates, physics, true, refused);
    if (!t) break;
    const std::vector<Selected> prior = sel;
    const size_t split = t->c->params.size();
    for (const Candidate* c : {t->c, t->c2}) {
      if (!c) continue;
      Selected s;
      s.c = *c;
      s.x = c == t->c ? std::vector<double>(t->x.begin(), t->x.begin() + static_cast<long>(split))
                      : std::vector<double>(t->x.begin() + static_cast<long>(split), t->x.end());
      s.report.physics = c->physics;
      s.report.chi2_drop_fit = t->gain_fit;
      s.report.chi2_drop_validation = t->gain_val;
      s.report.penalty = t->threshold_val;
      sel.push_back(std::move(s));
    }
    // The earlier selections were fitted without this one: let them settle
    // together, so that the next step sees what is really left. The step is
    // judged with them settled.
    if (sel.size() > 1) sel_engine.refit_all(sel, 2);
    const FrfData model_after = eval.model_frf(sel_engine.build(sel));
    const double nrmse_after = nrmse_of(model_after, measured);
    if (const double z = rise_in_noise_sd(model_now, model_after, measured, eval); z > kNoiseSd) {
      const std::string id = t->c->id + (t->c2 ? " + " + t->c2->id : std::string());
      progress("refused " + id + fmt(": chi2 on held-out lines -%.4g, but the NRMSE %.4f -> %.4f", t->gain_val, nrmse_before, nrmse_after) +
               fmt(" (%.3g sd of the noise)", z));
      sel = prior;
      refused.insert(t->c->id);
      if (t->c2) refused.insert(t->c2->id);
      if (++refusals > kRefusals) break;
      --steps;  // the same step again, without it
      continue;
    }
    refusals = 0;
    progress("accepted " + t->c->id + (t->c2 ? " + " + t->c2->id : std::string()) +
             fmt(": chi2 on held-out lines -%.4g (penalty %.4g), nrmse %.4f", t->gain_val, t->threshold_val, nrmse_after));
  }
  // The catalogue's limits first: when one resonant attachment fits as well
  // as the whole selection, the selection goes, and nothing is left to refine.
  std::optional<Selector::Attachment> attached;
  if (!res.mismatches.empty()) attached = sel_engine.attachment_challenge(sel);
  if (!sel.empty()) {
    sel_engine.fold_updates(sel);
    sel_engine.refit_all(sel);
    const size_t before_prune = sel.size();
    sel_engine.refine_locations(sel);
    sel_engine.prune(sel);
    if (sel.size() != before_prune && !sel.empty()) sel_engine.refit_all(sel);
  }
  if (!sel.empty()) {
    // Parsimony: one physics on the nominal model against the whole
    // selection. It is one step from the nominal: it must lower the NRMSE
    // from there, else the selection stays. (Each piece's reported NRMSE
    // before and after is set by the chain of the report below.)
    const PlantVariant nominal_variant = sel_engine.build({});
    const std::vector<Selected> selected = sel;
    if (const auto id = sel_engine.replace_by_single(sel, physics_candidates(nominal, view_of(nominal_variant)))) {
      const double before = nrmse_of(res.model_before, measured), after = nrmse_of(eval.model_frf(sel_engine.build(sel)), measured);
      if (!(after < before)) {
        progress("parsimony's " + *id + fmt(" would take the NRMSE from %.4f to %.4f: the selection stays", before, after));
        sel = selected;
      }
    }
  }
  std::vector<Selector::Alternative> alternatives;
  if (!sel.empty()) alternatives = sel_engine.alternatives(sel, physics_candidates(nominal, view_of(sel_engine.build(sel))));
  const detail::SpeedJudgement judged = detail::judge_at_other_speeds(sel_engine, others, sel, alternatives, progress);

  // 3. Report.
  auto improved_of = [&](const std::vector<Selected>& pieces) {
    PlantVariant v = sel_engine.build(pieces);
    v.plant.name = nominal.name + " (explained)";
    if (judged.law)  // the seal's speed law into its link's table (explain_speeds.h)
      for (const auto& s : pieces)
        if (s.c.physics == "seal_cross_coupling")
          for (auto& l : v.plant.links)
            if (l.name == s.c.location.value("link", "")) detail::write_speed_law(l, s.x[0], s.x[1], *judged.law, rpm);
    return v;
  };
  // The guarantee (docs/explain.md): the pieces in the order they were
  // chosen, each with its final values, each lower the NRMSE of the model
  // built so far, and each explanation reports that chain: its before and
  // after are the same figure of the final pieces without and with it (the
  // first before is the model's, the last after the improved model's). A
  // piece that would not lower it (the tidying and the other speeds refit,
  // move and replace pieces after they were chosen; within the noise a
  // step's NRMSE may rise) is not handed out. So the improved model never
  // fits the recording worse than the model it started from; when no piece
  // is left, nothing is explained, and the story and the unexplained bands
  // say why.
  std::string withdrawn;
  std::vector<std::string> dropped_story;
  if (!sel.empty()) {
    std::vector<Selected> chain;
    double now = nrmse_of(res.model_before, measured);
    for (const auto& s : sel) {
      std::vector<Selected> with = chain;
      with.push_back(s);
      const double after = nrmse_of(eval.model_frf(improved_of(with)), measured);
      if (after < now) {
        chain.push_back(s);
        chain.back().report.nrmse_before = now;
        chain.back().report.nrmse_after = now = after;
      } else {
        progress("not handed out: " + s.c.id + fmt(" would take the NRMSE from %.4f to %.4f", now, after));
        dropped_story.push_back("Not handed out: " + (s.c.is_update ? "the update " + s.c.id : s.c.physics + " at " + s.c.location.dump()) +
                                fmt(" lowers chi2 but with the final values would take the NRMSE from %.4f to %.4f.", now, after));
      }
    }
    if (chain.empty())
      withdrawn = fmt("Nothing explained: the %.0f piece(s) selected lower chi2, but none lowers the NRMSE of the model (", static_cast<double>(sel.size())) +
                  fmt("%.4f); an improved model never fits the recording worse than the model it started from.", nrmse_of(res.model_before, measured));
    if (chain.size() != sel.size()) {
      std::set<std::string> kept;
      for (const auto& c : chain) kept.insert(c.c.id);
      alternatives.erase(std::remove_if(alternatives.begin(), alternatives.end(), [&](const auto& a) { return !kept.count(a.claim_id); }),
                         alternatives.end());
      sel = std::move(chain);
    }
  }
  res.improved = improved_of(sel);
  res.model_after = eval.model_frf(res.improved);
  const FrfComparison cb = compare_frf(res.model_before, measured), ca = compare_frf(res.model_after, measured);
  res.nrmse_before = cb.nrmse;
  res.nrmse_after = ca.nrmse;
  double s2 = 0.0, h2 = 0.0;
  for (size_t e = 0; e < measured.entries.size(); ++e) {
    double es2 = 0.0, eh2 = 0.0;
    for (size_t l = 0; l < measured.freq_hz.size(); ++l) {
      es2 += eval.sigma(e, l) * eval.sigma(e, l);
      eh2 += std::norm(measured.entries[e].h[l]);
    }
    s2 += es2;
    h2 += eh2;
    const auto& b = cb.entries[e];
    const auto& a = ca.entries[e];
    const double lines = static_cast<double>(measured.freq_hz.size());
    res.entries.push_back({b.output, b.input, b.nrmse, a.nrmse, eh2 > 0 ? std::sqrt(es2 / eh2) : 0.0, b.chi2 / lines, a.chi2 / lines});
  }
  res.noise_floor_nrmse = h2 > 0 ? std::sqrt(s2 / h2) : 0.0;
  const double total_lines = static_cast<double>(measured.freq_hz.size() * measured.entries.size());
  res.chi2_per_line_before = cb.chi2 / total_lines;
  res.chi2_per_line_after = ca.chi2 / total_lines;

  std::vector<std::string> alt_story;
  for (const auto& s : sel) {
    if (s.c.is_update) {
      // Two factors on one coefficient (a seal's clearance and its direct
      // stiffness, say: both scale it, build() applies both) are one change
      // of it, from the model's value to the improved model's.
      for (const auto& ch : s.c.changes(s.x)) {
        const auto same = std::find_if(res.updated_parameters.begin(), res.updated_parameters.end(),
                                       [&](const ParameterChange& p) { return p.path == ch.path; });
        if (same == res.updated_parameters.end())
          res.updated_parameters.push_back(ch);
        else if (ch.from != 0.0)
          same->to *= ch.to / ch.from;
      }
      continue;
    }
    Explanation e = s.report;
    e.parameters = s.c.describe(s.x);
    e.location = s.c.location;
    e.evidence = s.c.signature + fmt("; chi2 on the fit lines -%.4g, on the held-out lines -%.4g (penalty %.4g)", e.chi2_drop_fit,
                                     e.chi2_drop_validation, e.penalty);
    if (const auto it = judged.refuted.find(s.c.id); it != judged.refuted.end()) {
      e.refuted = it->second;
      for (const auto& r : it->second)
        alt_story.push_back("The recordings at other speeds rule out " + r["physics"].get<std::string>() + " at " + r["location"].dump() +
                            " in place of " + s.c.physics + fmt(" (chi2 there higher by %.3g).", r["chi2_difference"].get<double>()));
    }
    if (const auto it = judged.exponent.find(s.c.id); it != judged.exponent.end()) {
      e.other_speeds = {{"speed_exponent", it->second}};
      e.parameters["speed_exponent"] = it->second;
    }
    for (const auto& a : alternatives) {
      if (a.claim_id != s.c.id) continue;
      e.alternatives.push_back(nlohmann::json{{"physics", a.c.physics},
                                {"parameters", a.c.describe(a.x)},
                                {"location", a.c.location},
                                {"chi2_difference", {{"fit", a.delta_fit}, {"held_out", a.delta_val}}},
                                {"evidence", a.c.signature}});
      alt_story.push_back("One recording cannot tell " + s.c.physics + " at " + s.c.location.dump() + " from " + a.c.physics + " at " +
                          a.c.location.dump() + fmt(" (chi2 differs by %.3g / %.3g on the fit / held-out lines): both are reported.", a.delta_fit, a.delta_val));
    }
    res.explanations.push_back(e);
  }

  const std::vector<Mode> modes_after = detail::modes_in_band(res.improved.plant, rpm, fmax);
  res.unexplained = locate_mismatches(res.improved.plant, res.model_after, eval, modes_after, options.window_threshold);
  if (!withdrawn.empty())
    for (auto& m : res.unexplained) m.evidence = withdrawn;
  std::string attached_story;
  if (attached) {
    const double f_hz = attached->x[0];
    Mismatch* band = nullptr;
    for (auto& m : res.unexplained)
      if (m.band_lo_hz <= f_hz && f_hz <= m.band_hi_hz && (!band || m.chi2_per_line > band->chi2_per_line)) band = &m;
    const int node = attached->c.impedance_node;
    const double z = attached->c.location.value("z_m", 0.0);
    const std::string what = fmt("an extra mode near %.1f Hz (zeta %.3f) that no physics of the catalogue produces; ", f_hz, attached->x[1]) +
                             fmt("it behaves like a part of %.3g kg on a spring attached to the rotor at node %.0f", attached->x[2], node) +
                             fmt(" (z = %.3f m), which the plant format cannot express", z);
    if (band) {
      band->located = nlohmann::json{{"like", "resonant_attachment"}, {"node", node}, {"z_m", z}, {"f_hz", f_hz}, {"zeta", attached->x[1]},
                                     {"kg", attached->x[2]}};
      band->evidence = what;
    }
    attached_story = "Not explained: " + what + ".";
  }
  if (!others.empty()) {
    res.other_speeds = others.report(nominal, res.improved, options.window_threshold);
    for (const auto& c : res.other_speeds)
      res.story.push_back(fmt("At %.0f rpm the improved model ", c.speed_rpm) +
                          (c.unexplained.empty() ? std::string("holds: ") : fmt("leaves %.0f band(s) beyond noise: ", static_cast<double>(c.unexplained.size()))) +
                          fmt("NRMSE %.4f -> %.4f", c.nrmse_before, c.nrmse_after) + fmt(" (noise floor %.4f).", c.noise_floor_nrmse));
  }
  res.modes = pair_modes(modes_before, modes_after);
  res.rotor_solves = eval.rotor_solves();
  res.evaluations = sel_engine.evaluations();

  // The story in plain sentences.
  if (res.mismatches.empty()) {
    res.story.push_back("The model matches the recording within its noise: nothing to explain.");
  } else {
    res.story.push_back(fmt("Model and recording differ beyond the noise in %.0f band(s); NRMSE %.4f (noise floor %.4f).",
                            static_cast<double>(res.mismatches.size()), res.nrmse_before, res.noise_floor_nrmse));
  }
  for (const auto& ch : res.updated_parameters)
    if (std::abs(ch.to - ch.from) > 1e-3 * std::abs(ch.from))
      res.story.push_back("Parameter " + ch.path + fmt(" corrected from %.5g to %.5g (x%.3f).", ch.from, ch.to, ch.from != 0 ? ch.to / ch.from : 0.0));
  for (const auto& e : res.explanations) res.story.push_back("Missing physics: " + e.physics + " " + e.parameters.dump() + " at " + e.location.dump() + ".");
  res.story.insert(res.story.end(), alt_story.begin(), alt_story.end());
  if (withdrawn.empty()) res.story.insert(res.story.end(), dropped_story.begin(), dropped_story.end());
  for (const auto& m : res.modes) {
    if (m.status == "extra")
      res.story.push_back(fmt("Mode at %.1f Hz (zeta %.1f %%) ", m.improved_f_hz, 100 * m.improved_zeta) + "is in the recording but not in the model: " + m.label + ".");
    else if (m.status == "shifted" || m.status == "damping_changed")
      res.story.push_back(m.label + " (" + m.whirl + fmt("): model %.1f Hz %.1f %%, ", m.model_f_hz, 100 * m.model_zeta) +
                          fmt("recording %.1f Hz %.1f %%.", m.improved_f_hz, 100 * m.improved_zeta));
  }
  if (!res.unexplained.empty()) res.story.push_back(std::to_string(res.unexplained.size()) + " band(s) remain unexplained (reported, not forced onto a candidate).");
  if (!attached_story.empty()) res.story.push_back(attached_story);
  if (!withdrawn.empty()) res.story.push_back(withdrawn);
  res.story.push_back(fmt("NRMSE %.4f -> %.4f (noise floor %.4f).", res.nrmse_before, res.nrmse_after, res.noise_floor_nrmse));
  return res;
}

nlohmann::json explain_to_json(const ExplainResult& r) {
  using nlohmann::json;
  auto band_json = [](const Mismatch& m, bool full) {
    json j = {{"outputs", m.outputs}, {"inputs", m.inputs}, {"band_hz", {m.band_lo_hz, m.band_hi_hz}}};
    if (full) {
      j["entries"] = m.entries;
      j["kind"] = m.kind;
      j["chi2_per_line"] = m.chi2_per_line;
      j["classification"] = m.classification;
      if (m.mode) j["mode"] = *m.mode;
    }
    return j;
  };
  auto num = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
  json out = {{"mismatches", json::array()}, {"explanations", json::array()}, {"unexplained", json::array()}, {"updated_parameters", json::array()}};
  for (const auto& m : r.mismatches) out["mismatches"].push_back(band_json(m, true));
  for (const auto& e : r.explanations) {
    json j = {{"physics", e.physics},       {"parameters", e.parameters},   {"parameters_sd", e.sd},
              {"location", e.location},     {"nrmse_before", e.nrmse_before}, {"nrmse_after", e.nrmse_after},
              {"evidence", e.evidence},     {"alternatives", e.alternatives}};
    if (!e.other_speeds.is_null()) j["other_speeds"] = e.other_speeds;
    if (!e.refuted.empty()) j["refuted"] = e.refuted;
    out["explanations"].push_back(j);
  }
  auto unexplained_json = [&](const Mismatch& m) {
    json j = band_json(m, false);
    j["kind"] = m.kind;
    j["chi2_per_line"] = m.chi2_per_line;
    if (m.located) j["located"] = *m.located;
    if (!m.evidence.empty()) j["evidence"] = m.evidence;
    return j;
  };
  for (const auto& m : r.unexplained) out["unexplained"].push_back(unexplained_json(m));
  if (!r.other_speeds.empty()) {
    out["other_speeds"] = json::array();
    for (const auto& c : r.other_speeds) {
      json bands = json::array();
      for (const auto& m : c.unexplained) bands.push_back(unexplained_json(m));
      out["other_speeds"].push_back({{"speed_rpm", c.speed_rpm},
                                     {"nrmse_before", c.nrmse_before},
                                     {"nrmse_after", c.nrmse_after},
                                     {"noise_floor_nrmse", c.noise_floor_nrmse},
                                     {"chi2_per_line_before", c.chi2_per_line_before},
                                     {"chi2_per_line_after", c.chi2_per_line_after},
                                     {"unexplained", bands}});
    }
  }
  for (const auto& c : r.updated_parameters) out["updated_parameters"].push_back({{"path", c.path}, {"from", c.from}, {"to", c.to}});
  out["nrmse_before"] = r.nrmse_before;
  out["nrmse_after"] = r.nrmse_after;
  out["noise_floor_nrmse"] = r.noise_floor_nrmse;
  out["chi2_per_line_before"] = r.chi2_per_line_before;
  out["chi2_per_line_after"] = r.chi2_per_line_after;
  out["entries"] = json::array();
  for (const auto& e : r.entries)
    out["entries"].push_back({{"output", e.output},
                              {"input", e.input},
                              {"nrmse_before", e.nrmse_before},
                              {"nrmse_after", e.nrmse_after},
                              {"noise_floor", e.noise_floor},
                              {"chi2_per_line_before", e.chi2_per_line_before},
                              {"chi2_per_line_after", e.chi2_per_line_after}});
  out["modes"] = json::array();
  for (const auto& m : r.modes)
    out["modes"].push_back({{"label", m.label},
                            {"direction", m.direction},
                            {"whirl", m.whirl},
                            {"status", m.status},
                            {"model_f_hz", num(m.model_f_hz)},
                            {"model_zeta", num(m.model_zeta)},
                            {"improved_f_hz", num(m.improved_f_hz)},
                            {"improved_zeta", num(m.improved_zeta)}});
  out["improved_model"] = variant_to_json(r.improved);
  out["story"] = r.story;
  return out;
}

}  // namespace ambdiag
