// The selection engine (explain_selector.h): construction, trials of
// candidates, the screening that ranks them, the greedy step.
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

Selector::Selector(const PlantModel& nominal, PlantFrfEvaluator& eval, const ExplainOptions& opt) : nominal_(nominal), eval_(eval), opt_(opt) {
  const size_t n = eval.measured().freq_hz.size();
  for (size_t l = 0; l < n; ++l) (l % 2 == 0 ? fit_ : val_).push_back(static_cast<int>(l));
  for (size_t l = 0; l < n; ++l) all_.push_back(static_cast<int>(l));
  const double n_real = 2.0 * static_cast<double>(eval.measured().entries.size() * fit_.size());
  penalty_per_param_ = 0.5 * std::log(n_real);
  // Lines of the linearised/grid screening: every other fit line when
  // there are many (ranking needs the shape, not every line).
  for (size_t k = 0; k < fit_.size(); k += fit_.size() > 200 ? 2 : 1) screen_lines_.push_back(fit_[k]);
}

PlantVariant Selector::build(const std::vector<Selected>& sel, const Candidate* extra, const std::vector<double>* xe,
                   const Candidate* extra2, size_t split) const {
  PlantVariant v{nominal_, 0.0};
  for (const auto& s : sel) s.c.apply(s.x, v);
  if (extra) {
    std::vector<double> a(xe->begin(), xe->begin() + static_cast<long>(split ? split : xe->size()));
    extra->apply(a, v);
    if (extra2) extra2->apply(std::vector<double>(xe->begin() + static_cast<long>(split), xe->end()), v);
  }
  return v;
}

std::vector<std::complex<double>> Selector::residual(const PlantVariant& v, const std::vector<int>& lines) {
  try {
    return eval_.residual(v, lines);
  } catch (const InputError&) {
    throw;
  } catch (const std::runtime_error& e) {
    progress(std::string("a trial model failed (") + e.what() + "): rejected");
    return std::vector<std::complex<double>>(eval_.measured().entries.size() * lines.size(), {1e30, 0.0});
  }
}

double Selector::threshold(int params, double chi2_now) const {
  return std::max(params, 1) * penalty_per_param_ + opt_.relative_penalty * chi2_now;
}

Trial Selector::try_candidate(const std::vector<Selected>& sel, const Candidate& c, const Candidate* c2, double cf, double cv,
                    const std::vector<double>* start) {
  std::vector<FitParameter> params = c.params;
  if (start)
    for (size_t i = 0; i < params.size(); ++i) params[i].initial = (*start)[i];
  const size_t split = c.params.size();
  if (c2) params.insert(params.end(), c2->params.begin(), c2->params.end());
  auto builder = [&](const std::vector<double>& x) { return build(sel, &c, &x, c2, split); };
  LeastSquaresOptions fo;
  fo.max_iterations = 6;
  fo.rel_tolerance = 1e-3;
  const LeastSquaresResult fr = fit_least_squares([&](const std::vector<double>& x) { return residual(builder(x), fit_); }, params, fo);
  evaluations_ += fr.evaluations;
  Trial t;
  t.c = &c;
  t.c2 = c2;
  t.x = fr.x;
  t.sd = fr.sd;
  t.chi2_fit = fr.chi2;
  t.chi2_val = chi2(builder(fr.x), val_);
  t.gain_fit = cf - t.chi2_fit;
  t.gain_val = cv - t.chi2_val;
  t.threshold_fit = threshold(static_cast<int>(params.size()), cf);
  t.threshold_val = threshold(static_cast<int>(params.size()), cv);
  return t;
}

double Selector::screen(const std::vector<Selected>& sel, const Candidate& c, const std::vector<std::complex<double>>& r0, double cf,
              const std::string& state, double delay_s, std::vector<double>* start) {
  // exp(-j w tau) of each residual element (entry-major over the fit lines).
  const FrfData& meas = eval_.measured();
  std::vector<std::complex<double>> phase(fit_.size());
  for (size_t k = 0; k < fit_.size(); ++k)
    phase[k] = std::polar(1.0, -2 * M_PI * meas.freq_hz[static_cast<size_t>(fit_[k])] * delay_s);
  const int p = c.screen_params >= 0 ? std::min<int>(c.screen_params, static_cast<int>(c.params.size()))
                                     : static_cast<int>(c.params.size());
  const std::vector<double> x0 = neutral(c);
  auto column = [&](int i) {
    // Columns are kept across steps even when the rotor changed: they rank
    // candidates; the full fit that follows evaluates exactly.
    const std::string key = (c.direction_key.empty() ? c.id : c.direction_key) + "#" + std::to_string(i);
    (void)state;
    if (auto it = dcache_.find(key); it == dcache_.end()) {
      std::vector<double> x = x0;
      double h = 1.0;  // a 0-parameter candidate: the whole change
      if (i >= 0) {
        h = 1e-3 * c.params[i].scale;
        if (x[i] + h > c.params[i].upper) h = -h;
        x[i] += h;
      }
      auto r = residual(build(sel, &c, &x), fit_);
      ++evaluations_;
      const double scale = i >= 0 ? c.params[i].scale / h : 1.0;
      // Stored without the delay, which multiplies every rotor change alike.
      for (size_t k = 0; k < r.size(); ++k) r[k] = (r[k] - r0[k]) * scale / phase[k % fit_.size()];
      dcache_.emplace(key, std::move(r));
    }
    std::vector<std::complex<double>> d = dcache_.at(key);
    for (size_t k = 0; k < d.size(); ++k) d[k] *= phase[k % fit_.size()];
    return d;
  };
  if (p == 0) {
    const auto d = column(-1);
    double c2 = 0.0;
    for (size_t k = 0; k < r0.size(); ++k) c2 += std::norm(r0[k] + d[k]);
    return cf - c2;
  }
  Eigen::MatrixXd jac(2 * static_cast<Eigen::Index>(r0.size()), p);
  for (int i = 0; i < p; ++i) {
    const auto d = column(i);
    for (size_t k = 0; k < r0.size(); ++k) {
      jac(2 * static_cast<Eigen::Index>(k), i) = d[k].real();
      jac(2 * static_cast<Eigen::Index>(k) + 1, i) = d[k].imag();
    }
  }
  Eigen::VectorXd rv(jac.rows());
  for (size_t k = 0; k < r0.size(); ++k) {
    rv(2 * static_cast<Eigen::Index>(k)) = r0[k].real();
    rv(2 * static_cast<Eigen::Index>(k) + 1) = r0[k].imag();
  }
  Eigen::VectorXd du = (jac.transpose() * jac).ldlt().solve(-jac.transpose() * rv);
  for (int i = 0; i < p; ++i) {  // respect the bounds
    const auto& fp = c.params[i];
    const double x = std::clamp(x0[i] + du(i) * fp.scale, fp.lower, fp.upper);
    du(i) = (x - x0[i]) / fp.scale;
  }
  if (start) {
    *start = x0;
    for (int i = 0; i < p; ++i) (*start)[i] = x0[i] + du(i) * c.params[i].scale;
  }
  return cf - (rv + jac * du).squaredNorm();
}

Selector::Cheap Selector::cheap_screen(detail::RotorScreen& scr, const Candidate& c, const std::vector<std::complex<double>>& r0,
                   const std::vector<std::complex<double>>& rv0, double cf, double cv, bool fit,
                   const std::vector<double>* start) {
  Cheap out;
  auto& slot = lowrank_[c.id];
  if (!slot.first) {
    slot.first = true;
    slot.second = scr.change_of(c);
  }
  if (!slot.second) return out;
  const detail::LowRankChange& ch = *slot.second;
  auto resid = [&](const std::vector<double>& x, const std::vector<int>& lines, const std::vector<std::complex<double>>& base) {
    return scr.residual_with(ch, c, x, lines, base);
  };
  out.ok = true;
  const std::vector<double> x0 = neutral(c);
  if (!fit || c.params.empty()) {
    // Linearised drop from one step per parameter (exact columns: dZ is linear).
    Eigen::MatrixXd jac(2 * static_cast<Eigen::Index>(screen_r0_.size()), static_cast<Eigen::Index>(c.params.size()));
    const auto d0 = resid(x0, screen_lines_, screen_r0_);
    for (size_t i = 0; i < c.params.size(); ++i) {
      std::vector<double> x = x0;
      double h = 1e-3 * c.params[i].scale;
      if (x[i] + h > c.params[i].upper) h = -h;
      x[i] += h;
      const auto d = resid(x, screen_lines_, screen_r0_);
      for (size_t k = 0; k < d.size(); ++k) {
        const auto col = (d[k] - d0[k]) * (c.params[i].scale / h);
        jac(2 * static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(i)) = col.real();
        jac(2 * static_cast<Eigen::Index>(k) + 1, static_cast<Eigen::Index>(i)) = col.imag();
      }
    }
    Eigen::VectorXd rv(jac.rows());
    for (size_t k = 0; k < d0.size(); ++k) {
      rv(2 * static_cast<Eigen::Index>(k)) = d0[k].real();
      rv(2 * static_cast<Eigen::Index>(k) + 1) = d0[k].imag();
    }
    out.x = x0;
    if (c.params.empty()) {
      out.gain_fit = cf - chi2_of(resid(x0, fit_, r0));
      out.gain_val = cv - chi2_of(resid(x0, val_, rv0));
      return out;
    }
    Eigen::VectorXd du = (jac.transpose() * jac).ldlt().solve(-jac.transpose() * rv);
    for (size_t i = 0; i < c.params.size(); ++i) {
      const auto& fp = c.params[i];
      out.x[i] = std::clamp(x0[i] + du(static_cast<Eigen::Index>(i)) * fp.scale, fp.lower, fp.upper);
    }
    out.gain_fit = screen_cf_ - chi2_of(resid(out.x, screen_lines_, screen_r0_));
    // A large change is far from linear (a mode moves by more than its
    // bandwidth): also try a grid over the first parameter's range,
    // geometric for factors and masses that span decades, and keep the
    // best point actually evaluated.
    const FitParameter& fp = c.params[0];
    const bool geometric = fp.lower > 0 && fp.upper > 4 * fp.lower;
    auto at = [&](double t) {
      std::vector<double> x = x0;
      if (geometric) x[0] = fp.lower * std::pow(fp.upper / fp.lower, t);
      else if (fp.lower == 0.0 && fp.upper > 0.0) x[0] = fp.upper * std::pow(1e-3, 1.0 - t);  // masses: decades up to the bound
      else x[0] = fp.lower + t * (fp.upper - fp.lower);
      return x;
    };
    auto gain_at = [&](double t) { return screen_cf_ - chi2_of(resid(at(t), screen_lines_, screen_r0_)); };
    constexpr int kGrid = 8;
    double best_t = -1.0, best_grid = -std::numeric_limits<double>::infinity();
    for (int g = 0; g < kGrid; ++g) {
      const double t = (g + 0.5) / kGrid;
      const double gain = gain_at(t);
      if (gain > best_grid) best_grid = gain, best_t = t;
    }
    // Where the grid beats the linear step the change is far from linear:
    // refine the grid's best cell by golden section (10 evaluations narrow
    // it to 0.2 % of the range in t), so that the ranking below compares
    // candidates at their optimum, not at whichever grid point fell
    // nearest to it.
    if (best_grid > out.gain_fit) {
      double a = std::max(0.0, best_t - 1.0 / kGrid), b = std::min(1.0, best_t + 1.0 / kGrid);
      const double r = 0.5 * (std::sqrt(5.0) - 1.0);
      double t1 = b - r * (b - a), t2 = a + r * (b - a);
      double g1 = gain_at(t1), g2 = gain_at(t2);
      for (int k = 0; k < 10; ++k) {
        if (g1 > g2) {
          b = t2, t2 = t1, g2 = g1;
          t1 = b - r * (b - a), g1 = gain_at(t1);
        } else {
          a = t1, t1 = t2, g1 = g2;
          t2 = a + r * (b - a), g2 = gain_at(t2);
        }
      }
      const double t_best = g1 > g2 ? t1 : t2;
      const double g_best = std::max({g1, g2, best_grid});
      out.gain_fit = g_best;
      out.x = g_best == best_grid ? at(best_t) : at(t_best);
    }
    return out;
  }
  LeastSquaresOptions fo;
  fo.max_iterations = 30;  // the low-rank model is cheap: converge, so that candidates rank at their optimum
  fo.rel_tolerance = 1e-7;
  std::vector<FitParameter> params = c.params;
  if (start)
    for (size_t i = 0; i < params.size(); ++i) params[i].initial = (*start)[i];
  const LeastSquaresResult fr = fit_least_squares([&](const std::vector<double>& x) { return resid(x, fit_, r0); }, params, fo);
  out.x = fr.x;
  out.gain_fit = cf - fr.chi2;
  out.gain_val = cv - chi2_of(resid(fr.x, val_, rv0));
  return out;
}

bool Selector::has_lowrank(detail::RotorScreen& scr, const Candidate& c) {
  auto& slot = lowrank_[c.id];
  if (!slot.first) {
    slot.first = true;
    slot.second = scr.change_of(c);
  }
  return slot.second.has_value();
}

detail::RotorScreen& Selector::screen_for(const std::vector<Selected>& sel, const PlantVariant& cur) {
  std::string key;
  for (const auto& s : sel)
    if (s.c.touches_rotor || s.c.physics == "acquisition_delay") key += s.c.id + "|";
  if (!screen_ || key != screen_key_) {
    screen_ = std::make_unique<detail::RotorScreen>(cur, eval_);
    screen_key_ = key;
    lowrank_.clear();
    stale_gain_.clear();
  }
  return *screen_;
}

Trial Selector::evaluate_fixed(const std::vector<Selected>& sel, const Candidate& c, double cf, double cv) {
  Trial t;
  t.c = &c;
  const std::vector<double> x;
  t.chi2_fit = chi2(build(sel, t.c, &x), fit_);
  t.chi2_val = chi2(build(sel, t.c, &x), val_);
  evaluations_ += 2;
  t.gain_fit = cf - t.chi2_fit;
  t.gain_val = cv - t.chi2_val;
  t.threshold_fit = threshold(1, cf);
  t.threshold_val = threshold(1, cv);
  return t;
}

std::optional<Trial> Selector::step(const std::vector<Selected>& sel, const std::vector<Candidate>& updates,
                          const std::vector<Candidate>& physics, bool pairs, const std::set<std::string>& refused) {
  const PlantVariant cur = build(sel);
  const auto r0 = residual(cur, fit_);
  const double cf = chi2_of(r0), cv = chi2(cur, val_);
  const std::string state = eval_.rotor_key(cur.plant);
  std::vector<Trial> trials;
  struct Screened {
    double gain;
    const Candidate* c;
    std::vector<double> start;
    bool fresh = true;
  };
  std::vector<Screened> rotor;
  detail::RotorScreen& scr = screen_for(sel, cur);
  const auto rv0 = residual(cur, val_);
  screen_r0_ = residual(cur, screen_lines_);
  screen_cf_ = chi2_of(screen_r0_);
  std::vector<Screened> lowrank[2];  // updates, physics with a low-rank model
  for (const auto* pool : {&updates, &physics}) {
    for (const auto& c : *pool) {
      if (is_selected(sel, c) || refused.count(c.id)) continue;
      if (c.touches_rotor) {
        Screened sc{0.0, &c, {}};
        if (has_lowrank(scr, c)) {
          // Lazy greedy: a drop screened in an earlier step on this screen
          // bounds the drop now (what is explained only grows); only the
          // candidates that could reach the top are screened again below.
          const auto it = stale_gain_.find(c.id);
          if (it != stale_gain_.end()) {
            sc.gain = it->second.first;
            sc.start = it->second.second;
            sc.fresh = false;
          } else {
            const Cheap ch = cheap_screen(scr, c, r0, rv0, cf, cv, false);
            sc.gain = ch.gain_fit;
            sc.start = ch.x;
            stale_gain_[c.id] = {sc.gain, sc.start};
          }
          lowrank[c.is_update ? 0 : 1].push_back(std::move(sc));
          continue;
        }
        sc.gain = screen(sel, c, r0, cf, state, cur.delay_s, &sc.start);
        rotor.push_back(std::move(sc));
      }
      else trials.push_back(try_candidate(sel, c, nullptr, cf, cv));
    }
  }
  // The best few by the linearised drop are fitted on the low-rank model;
  // they rank by the smaller of their drops on the two halves.
  const auto by_gain = [](const Screened& a, const Screened& b) { return a.gain > b.gain; };
  for (auto& list : lowrank) {
    const size_t top = std::min(list.size(), static_cast<size_t>(opt_.lowrank_fitted));
    for (bool stale = true; stale;) {
      std::sort(list.begin(), list.end(), by_gain);
      stale = false;
      for (size_t k = 0; k < top; ++k) {
        if (list[k].fresh) continue;
        const Cheap ch = cheap_screen(scr, *list[k].c, r0, rv0, cf, cv, false);
        list[k].gain = ch.gain_fit;
        list[k].start = ch.x;
        list[k].fresh = stale = true;
        stale_gain_[list[k].c->id] = {ch.gain_fit, ch.x};
      }
    }
    // Near-ties of the screen (within 5 % of the best: the screen varies
    // one parameter) are all fitted: a stiffness at the shaft end and one
    // a node further in screen alike and differ once their damping is fitted.
    size_t keep = top;
    while (keep < list.size() && keep < 12 && list[keep].gain >= 0.95 * list[0].gain && list[0].gain > 0.0) {
      if (!list[keep].fresh) {  // a bound from an earlier step: screen it now
        const Cheap ch = cheap_screen(scr, *list[keep].c, r0, rv0, cf, cv, false);
        list[keep].gain = ch.gain_fit;
        list[keep].start = ch.x;
        list[keep].fresh = true;
        stale_gain_[list[keep].c->id] = {ch.gain_fit, ch.x};
        if (list[keep].gain < 0.95 * list[0].gain) break;
      }
      ++keep;
    }
    list.resize(keep);
    // Fitted on the low-rank model, they compete as trials; the FE fit
    // follows only for the one that wins (below).
    for (auto& sc : list) {
      const Cheap ch = cheap_screen(scr, *sc.c, r0, rv0, cf, cv, true, &sc.start);
      Trial t;
      t.c = sc.c;
      t.x = ch.x;
      t.cheap = true;
      t.gain_fit = ch.gain_fit;
      t.gain_val = ch.gain_val;
      t.chi2_fit = cf - ch.gain_fit;
      t.chi2_val = cv - ch.gain_val;
      t.threshold_fit = threshold(static_cast<int>(sc.c->params.size()), cf);
      t.threshold_val = threshold(static_cast<int>(sc.c->params.size()), cv);
      trials.push_back(t);
    }
  }
  std::sort(rotor.begin(), rotor.end(), [](const Screened& a, const Screened& b) { return a.gain > b.gain; });
  // Fit fully the best screened updates and physics, from their linearised
  // optimum; a linearised drop well below the penalty or the best one is
  // not pursued.
  int fitted_updates = 0, fitted_physics = 0;
  double best_closed = 0.0;  // FE candidates far behind a closed-form one are not pursued
  for (const auto& t : trials)
    if (t.passes()) best_closed = std::max(best_closed, t.gain_fit);
  double best_gain[2] = {0.3 * best_closed, 0.3 * best_closed};
  for (const auto& sc : rotor) {
    const int cls = sc.c->is_update ? 0 : 1;
    int& n = cls == 0 ? fitted_updates : fitted_physics;
    best_gain[cls] = std::max(best_gain[cls], sc.gain);
    if (n >= opt_.rotor_candidates_fitted || sc.gain < 0.5 * threshold(static_cast<int>(sc.c->params.size()), cf) ||
        sc.gain < 0.3 * best_gain[cls])
      continue;
    ++n;
    trials.push_back(sc.c->params.empty() ? evaluate_fixed(sel, *sc.c, cf, cv) : try_candidate(sel, *sc.c, nullptr, cf, cv, &sc.start));
  }
  progress(fmt("step: %.0f closed-form and %.0f FE candidates screened, ", static_cast<double>(trials.size() - fitted_updates - fitted_physics),
               static_cast<double>(rotor.size())) +
           fmt("%.0f FE fitted; %.0f rotor solves so far", fitted_updates + fitted_physics, eval_.rotor_solves()));
  // The winner; one judged on the low-rank model is fitted on the FE model
  // (from its low-rank optimum) and must win again with exact figures.
  for (int round = 0; round < 6; ++round) {
    Trial* best_update = nullptr;
    Trial* best_physics = nullptr;
    for (auto& t : trials) {
      if (!t.passes()) continue;
      Trial*& b = t.c->is_update ? best_update : best_physics;
      if (!b || t.margin() > b->margin()) b = &t;
    }
    Trial* win = best_update && (!best_physics || best_update->gain_val >= 0.8 * best_physics->gain_val) ? best_update : best_physics;
    if (!win) break;
    if (!win->cheap) return *win;
    *win = win->c->params.empty() ? evaluate_fixed(sel, *win->c, cf, cv) : try_candidate(sel, *win->c, nullptr, cf, cv, &win->x);
  }
  if (!pairs) return std::nullopt;
  for (auto& t : trials)  // pairs below are fitted on the FE model
    t.cheap = false;
  // No single candidate pays: the best pair among the three best singles.
  std::sort(trials.begin(), trials.end(), [](const Trial& a, const Trial& b) { return a.gain_val > b.gain_val; });
  std::optional<Trial> best_pair;
  for (size_t a = 0; a < std::min<size_t>(3, trials.size()); ++a) {
    for (size_t b = a + 1; b < std::min<size_t>(3, trials.size()); ++b) {
      if (trials[a].gain_val <= 0 || trials[b].gain_val <= 0 || trials[a].c->id == trials[b].c->id) continue;
      Trial t = try_candidate(sel, *trials[a].c, trials[b].c, cf, cv);
      if (t.passes() && (!best_pair || t.margin() > best_pair->margin())) best_pair = t;
    }
  }
  return best_pair;
}

bool Selector::is_selected(const std::vector<Selected>& sel, const Candidate& c) {
  for (const auto& s : sel)
    if (s.c.id == c.id) return true;
  return false;
}

void Selector::progress(const std::string& s) const {
  if (opt_.progress) opt_.progress(s);
}

}  // namespace ambdiag::detail
