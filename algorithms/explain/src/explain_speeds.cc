#include "explain_speeds.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>

#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/core/error.h"
#include "explain_locate.h"
#include "explain_selector.h"

namespace ambdiag::detail {

OtherSpeeds::OtherSpeeds(const std::vector<FrfData>& recordings, double primary_rpm) : primary_rpm_(primary_rpm) {
  for (size_t k = 0; k < recordings.size(); ++k) {
    const auto& r = recordings[k];
    const auto run_id = r.meta("run_id");
    const std::string which = "recording " + std::to_string(k + 2) + (run_id ? " (" + *run_id + ")" : "");
    if (!r.speed_rpm || !(*r.speed_rpm > 0.0))
      throw InputError(which + ": speed_rpm: a recording at another speed must state its speed (> 0)");
    // Equal speeds add noise averaging, not a speed law: refused so that a
    // repeated file is not taken for evidence it is not.
    if (std::abs(*r.speed_rpm - primary_rpm) <= 1e-3 * primary_rpm)
      throw InputError(which + ": speed_rpm: " + std::to_string(*r.speed_rpm) + " is the first recording's speed, not another one");
    evals_.emplace_back(r);
  }
}

std::vector<std::complex<double>> OtherSpeeds::residual(const std::function<PlantVariant(double scale)>& build, double exponent) {
  std::vector<std::complex<double>> out;
  for (auto& e : evals_) {
    std::vector<int> lines(e.measured().freq_hz.size());
    for (size_t l = 0; l < lines.size(); ++l) lines[l] = static_cast<int>(l);
    try {
      const auto r = e.residual(build(std::pow(*e.measured().speed_rpm / primary_rpm_, exponent)), lines);
      out.insert(out.end(), r.begin(), r.end());
    } catch (const InputError&) {
      throw;
    } catch (const std::runtime_error&) {
      out.insert(out.end(), e.measured().entries.size() * lines.size(), {1e30, 0.0});
    }
  }
  return out;
}

std::vector<SpeedCheck> OtherSpeeds::report(const PlantModel& nominal, const PlantVariant& after, double window_threshold) {
  std::vector<SpeedCheck> out;
  for (auto& e : evals_) {
    const FrfData& meas = e.measured();
    SpeedCheck s;
    s.speed_rpm = *meas.speed_rpm;
    const PlantVariant before{nominal, 0.0};
    const FrfData model_before = e.model_frf(before), model_after = e.model_frf(after);
    const FrfComparison cb = compare_frf(model_before, meas), ca = compare_frf(model_after, meas);
    const double lines = static_cast<double>(meas.freq_hz.size() * meas.entries.size());
    s.nrmse_before = cb.nrmse;
    s.nrmse_after = ca.nrmse;
    s.chi2_per_line_before = cb.chi2 / lines;
    s.chi2_per_line_after = ca.chi2 / lines;
    double s2 = 0.0, h2 = 0.0;
    for (size_t k = 0; k < meas.entries.size(); ++k)
      for (size_t l = 0; l < meas.freq_hz.size(); ++l) {
        s2 += e.sigma(k, l) * e.sigma(k, l);
        h2 += std::norm(meas.entries[k].h[l]);
      }
    s.noise_floor_nrmse = h2 > 0 ? std::sqrt(s2 / h2) : 0.0;
    const auto modes = modes_in_band(after.plant, s.speed_rpm, meas.freq_hz.back());
    s.unexplained = locate_mismatches(after.plant, model_after, e, modes, window_threshold);
    out.push_back(std::move(s));
  }
  return out;
}

void write_speed_law(Link& l, double k, double c, double exponent, double rpm0) {
  std::vector<double> rpms;
  for (int i = 0; i <= 8; ++i) rpms.push_back(rpm0 * (0.5 + 0.125 * i));
  for (const auto& row : l.table) rpms.push_back(row.rpm);
  std::sort(rpms.begin(), rpms.end());
  rpms.erase(std::unique(rpms.begin(), rpms.end(), [](double a, double b) { return std::abs(a - b) <= 1e-9 * std::max(1.0, b); }),
             rpms.end());
  std::array<bool, static_cast<size_t>(kLinkCoefCount)> stated{};
  for (const auto& row : l.table)
    for (size_t i = 0; i < static_cast<size_t>(kLinkCoefCount); ++i) stated[i] = stated[i] || row.values[i].has_value();
  const auto at = [](LinkCoef cf) { return static_cast<size_t>(cf); };
  for (LinkCoef cf : {LinkCoef::kxy, LinkCoef::kyx, LinkCoef::cxy, LinkCoef::cyx}) stated[at(cf)] = true;
  std::vector<LinkTableRow> table;
  for (double rpm : rpms) {
    const LinkCoefficients v = l.at_speed(rpm);
    const double extra = std::pow(rpm / rpm0, exponent) - 1.0;  // the law beyond what rpm0's values hold
    LinkTableRow row;
    row.rpm = rpm;
    for (size_t i = 0; i < static_cast<size_t>(kLinkCoefCount); ++i)
      if (stated[i]) row.values[i] = v[i];
    *row.values[at(LinkCoef::kxy)] += k * extra;
    *row.values[at(LinkCoef::kyx)] -= k * extra;
    *row.values[at(LinkCoef::cxy)] += c * extra;
    *row.values[at(LinkCoef::cyx)] -= c * extra;
    table.push_back(row);
  }
  l.table = std::move(table);
}

std::vector<Selected> scaled_law(std::vector<Selected> sel, double scale) {
  for (auto& s : sel)
    if (s.c.physics == "seal_cross_coupling")
      for (auto& v : s.x) v *= scale;
  return sel;
}

bool has_law(const std::vector<Selected>& sel) {
  return std::any_of(sel.begin(), sel.end(), [](const Selected& s) { return s.c.physics == "seal_cross_coupling"; });
}


SpeedJudgement judge_at_other_speeds(Selector& engine, OtherSpeeds& others, std::vector<Selected>& sel,
                                     std::vector<Selector::Alternative>& alternatives,
                                     const std::function<void(const std::string&)>& progress) {
  SpeedJudgement out;
  if (others.empty() || sel.empty()) return out;
  constexpr double kDecisive = 2.0 * 4.605170185988092;  // 2 ln 100
  struct Joint {
    std::vector<double> x;
    std::optional<double> exponent;
    double chi2 = 0.0;
  };
  // Piece k of `s` (and the law) fitted to every recording, the rest held.
  const auto joint_fit = [&](const std::vector<Selected>& s, size_t k) {
    const bool law = has_law(s);
    const size_t np = s[k].c.params.size();
    std::vector<FitParameter> params = s[k].c.params;
    for (size_t i = 0; i < np; ++i) params[i].initial = s[k].x[i];
    if (law) params.push_back({"speed_exponent", 1.0, 0.0, 3.0, 0.1});
    const auto residual = [&](const std::vector<double>& x) {
      std::vector<Selected> t = s;
      t[k].x.assign(x.begin(), x.begin() + static_cast<long>(np));
      auto r = engine.residual(engine.build(t), engine.all_lines());
      const auto r2 = others.residual([&](double scale) { return engine.build(scaled_law(t, scale)); }, law ? x[np] : 0.0);
      r.insert(r.end(), r2.begin(), r2.end());
      return r;
    };
    LeastSquaresOptions fo;
    fo.max_iterations = 10;
    const LeastSquaresResult fr = fit_least_squares(residual, params, fo);
    Joint j;
    j.x.assign(fr.x.begin(), fr.x.begin() + static_cast<long>(np));
    if (law) j.exponent = fr.x[np];
    j.chi2 = fr.chi2;
    return j;
  };
  bool judged_law = false;
  for (size_t k = 0; k < sel.size(); ++k) {
    if (sel[k].c.is_update) continue;
    std::vector<size_t> mine;
    for (size_t a = 0; a < alternatives.size(); ++a)
      if (alternatives[a].claim_id == sel[k].c.id) mine.push_back(a);
    if (mine.empty()) continue;
    // Everyone in the claim's place: the claim first, then each alternative.
    struct Option {
      Candidate c;
      Joint fit;
    };
    std::vector<Option> opts{{sel[k].c, joint_fit(sel, k)}};
    for (size_t a : mine) {
      std::vector<Selected> s = sel;
      s[k].c = alternatives[a].c;
      s[k].x = alternatives[a].x;
      opts.push_back({alternatives[a].c, joint_fit(s, k)});
    }
    size_t best = 0;
    for (size_t i = 1; i < opts.size(); ++i)
      if (opts[i].fit.chi2 < opts[best].fit.chi2) best = i;
    if (best != 0 && opts[0].fit.chi2 - opts[best].fit.chi2 <= kDecisive) best = 0;  // not decisive: the claim stays
    for (size_t i = 0; i < opts.size(); ++i)
      progress("other speeds: " + opts[i].c.id + fmt(" chi2 over every recording %.6g", opts[i].fit.chi2) + (i == best ? " (kept)" : ""));
    const std::string old_id = sel[k].c.id;
    if (best != 0) {
      progress("other speeds: " + opts[best].c.id + " replaces " + old_id);
      sel[k].c = opts[best].c;
      sel[k].report.physics = opts[best].c.physics;
    }
    sel[k].x = opts[best].fit.x;
    if (opts[best].fit.exponent) out.law = opts[best].fit.exponent, judged_law = true;
    nlohmann::json refuted = nlohmann::json::array();
    std::vector<Selector::Alternative> kept;
    for (size_t i = 0; i < opts.size(); ++i) {
      if (i == best) continue;
      const double d = opts[i].fit.chi2 - opts[best].fit.chi2;
      if (d > kDecisive) {
        refuted.push_back({{"physics", opts[i].c.physics},
                           {"parameters", opts[i].c.describe(opts[i].fit.x)},
                           {"location", opts[i].c.location},
                           {"chi2_difference", d},
                           {"evidence", "fits the recordings at every speed worse: " + opts[i].c.signature}});
      } else {
        kept.push_back(i == 0 ? Selector::Alternative{old_id, opts[0].c, opts[0].fit.x, d, d} : alternatives[mine[i - 1]]);
        kept.back().claim_id = sel[k].c.id;
        kept.back().x = opts[i].fit.x;
      }
    }
    std::vector<Selector::Alternative> rest;
    for (auto& a : alternatives)
      if (a.claim_id != old_id) rest.push_back(std::move(a));
    rest.insert(rest.end(), kept.begin(), kept.end());
    alternatives = std::move(rest);
    if (!refuted.empty()) out.refuted[sel[k].c.id] = refuted;
  }
  // A seal's law not yet fitted (its claim had no alternatives): fitted with it.
  if (has_law(sel) && !judged_law)
    for (size_t k = 0; k < sel.size(); ++k)
      if (sel[k].c.physics == "seal_cross_coupling") {
        const Joint j = joint_fit(sel, k);
        sel[k].x = j.x;
        out.law = j.exponent;
        break;
      }
  if (out.law) progress(fmt("other speeds: the seal's cross-coupling grows with speed^%.3f", *out.law));
  if (out.law)
    for (const auto& s : sel)
      if (s.c.physics == "seal_cross_coupling") out.exponent[s.c.id] = *out.law;
  return out;
}

}  // namespace ambdiag::detail
