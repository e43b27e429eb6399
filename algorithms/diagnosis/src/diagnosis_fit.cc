// Fitting fault hypotheses to a measured change: the model grid, the
// screening by one probe evaluation, the refinement by Levenberg-Marquardt
// with Broyden updates (diagnosis.h, docs/diagnosis.md section 4). Shared by
// the same-speed diagnosis and the operating-reference one.
#include <algorithm>
#include <cmath>
#include <limits>

#include "ambdiag/algorithms/model/frf_compare.h"
#include "diagnosis_internal.h"

namespace ambdiag::diagnosis_detail {

ModelGrid::ModelGrid(const PlantModel& plant, const Aligned& a, std::function<void(Values&)> transform)
    : plant_(plant), transform_(std::move(transform)) {
  skeleton_.speed_rpm = a.speed_rpm;
  skeleton_.freq_hz = a.freq_hz;
  for (const auto& e : a.entries) skeleton_.entries.push_back({e.output, e.input, {}, {}, {}});
  options_.method = FrfMethod::modal;
  options_.modal_basis = ModalBasis::krylov;
  options_.damping.modes = StructuralDampingOptions::Modes::band;
  nominal_ = evaluate(plant);
}

Values ModelGrid::raw(const PlantModel& p) {
  ++evaluations_;
  const FrfData f = model_frf_like(p, skeleton_, options_);
  Values v;
  for (const auto& e : f.entries) v.push_back(e.h);
  return v;
}

Values ModelGrid::evaluate(const PlantModel& p) {
  Values v = raw(p);
  if (transform_) transform_(v);
  return v;
}

const Values& ModelGrid::evaluate(const FaultHypothesis& h, size_t id, double x) {
  auto& memo = cache_[id];
  for (const auto& [xm, v] : memo)
    if (xm == x) return v;
  memo.emplace_back(x, evaluate(apply_fault(plant_, h, x)));
  return memo.back().second;
}

// The weighted target: measured, 1 / sigma, and the offset (reference mean
// - nominal model) that turns a model into the prediction
// m + H(p) - H(nominal).
FrfFitTarget make_target(const Aligned& a, const ModelGrid& g) {
  FrfFitTarget t;
  t.freq_hz = a.freq_hz;
  for (size_t e = 0; e < a.entries.size(); ++e) {
    const auto& en = a.entries[e];
    std::vector<std::complex<double>> o(en.h.size());
    std::vector<double> w(en.h.size());
    for (size_t l = 0; l < en.h.size(); ++l) {
      w[l] = 1.0 / std::sqrt(en.var[l]);
      o[l] = en.mean[l] - g.nominal()[e][l];
    }
    t.measured.push_back(en.h);
    t.weight.push_back(std::move(w));
    t.offset.push_back(std::move(o));
  }
  return t;
}

// Where the screening evaluates each kind: a change well above the noise,
// inside the bounds.
double probe_value(const FaultHypothesis& h) {
  switch (h.kind) {
    case FaultKind::dry_run: return 0.5;
    case FaultKind::balance_piston_wear:
    case FaultKind::impeller_seal_wear: return 1.5;
    default: return 0.7;
  }
}


Screened screen(const FaultHypothesis& h, size_t id, ModelGrid& g, const FrfFitTarget& t) {
  Screened s{id, probe_value(h), 0.0, h.nominal, fit_chi2(t, g.evaluate(h, id, probe_value(h)))};
  const Values& v = g.evaluate(h, id, s.probe);
  const double dx = s.probe - h.nominal;
  double num = 0.0, den = 0.0;
  for (size_t e = 0; e < v.size(); ++e)
    for (size_t l = 0; l < v[e].size(); ++l) {
      const double w = t.weight[e][l];
      const std::complex<double> j = w * (v[e][l] - g.nominal()[e][l]) / dx;
      // residual at the nominal parameter: w (H0 + offset - H) = w (m - H)
      const std::complex<double> r0 = w * (g.nominal()[e][l] + t.offset[e][l] - t.measured[e][l]);
      num -= (std::conj(j) * r0).real();
      den += std::norm(j);
    }
  if (den > 0.0) {
    // Linearised step from the nominal value, kept inside the bounds.
    const double step = std::clamp(num / den, h.lower - h.nominal, h.upper - h.nominal);
    s.drop = 2.0 * step * num - step * step * den;
    s.x_lin = h.nominal + step;
  }
  return s;
}

// Start values tried before refining: the chi2 of a resonance shift is not
// convex in a stiffness or seal factor (a mode half-way to the measured one
// fits worse than none), so a coarse look over the range comes first.
std::vector<double> start_grid(const FaultHypothesis& h) {
  switch (h.kind) {
    case FaultKind::dry_run: return {0.0, 0.25, 0.5, 0.75};
    case FaultKind::balance_piston_wear:
    case FaultKind::impeller_seal_wear: return {1.15, 1.5, 2.2, 3.5, 6.0};
    default: return {0.35};  // with the probe 0.7 and the linearised estimate
  }
}

// The secant between two evaluated points as a Jacobian of the real
// weighted residual.
Eigen::MatrixXd secant(const Values& v1, double x1, const Values& v0, double x0, const FrfFitTarget& t) {
  Eigen::MatrixXd j(2 * t.values(), 1);
  Eigen::Index k = 0;
  for (size_t e = 0; e < v1.size(); ++e)
    for (size_t l = 0; l < v1[e].size(); ++l) {
      const std::complex<double> d = t.weight[e][l] * (v1[e][l] - v0[e][l]) / (x1 - x0);
      j(k++, 0) = d.real();
      j(k++, 0) = d.imag();
    }
  return j;
}


// Start from the best of the nominal value and the start grid, with the
// secant to its better neighbour as the first Jacobian; then
// Levenberg-Marquardt with Broyden updates, about one model evaluation per
// iteration.
Fitted refine(const FaultHypothesis& h, const Screened& s, ModelGrid& g, const FrfFitTarget& t) {
  std::vector<double> xs = start_grid(h);
  xs.push_back(h.nominal);
  xs.push_back(s.probe);
  xs.push_back(s.x_lin);
  std::sort(xs.begin(), xs.end());
  xs.erase(std::unique(xs.begin(), xs.end()), xs.end());
  std::vector<double> c(xs.size());
  auto values_at = [&](double x) -> const Values& { return x == h.nominal ? g.nominal() : g.evaluate(h, s.id, x); };
  size_t best = 0;
  for (size_t i = 0; i < xs.size(); ++i) {
    c[i] = fit_chi2(t, values_at(xs[i]));
    if (c[i] < c[best]) best = i;
  }
  size_t nb = best == 0 ? 1 : best + 1 == xs.size() ? best - 1 : (c[best - 1] < c[best + 1] ? best - 1 : best + 1);
  LeastSquaresOptions o = secant_fit_options(12, 1e-7, 1e-5);
  o.jacobian0 = secant(values_at(xs[best]), xs[best], values_at(xs[nb]), xs[nb], t);
  const LeastSquaresResult r = fit_parameters(
      [&](const std::vector<double>& p) { return p[0] == h.nominal ? g.nominal() : g.evaluate(h, s.id, p[0]); }, t,
      {{h.parameter, xs[best], h.lower, h.upper}}, o);
  const double sd = r.covariance(0, 0) > 0.0 ? std::sqrt(r.covariance(0, 0)) : std::numeric_limits<double>::infinity();
  return {r.x[0], sd, r.chi2};
}

double nrmse_of(const Values& model, const Aligned& a) {
  double d2 = 0.0, m2 = 0.0;
  for (size_t e = 0; e < a.entries.size(); ++e)
    for (size_t l = 0; l < a.freq_hz.size(); ++l) {
      d2 += std::norm(model[e][l] - a.entries[e].h[l]);
      m2 += std::norm(a.entries[e].h[l]);
    }
  return m2 > 0.0 ? std::sqrt(d2 / m2) : 0.0;
}

std::string location_of(const FaultHypothesis& h, const PlantModel& plant, FaultEstimate& f) {
  if (!h.channel.empty()) return (h.kind == FaultKind::sensor_fault ? "sensor " : "actuator ") + h.channel;
  if (!h.elements.empty()) {
    const auto z = plant.node_positions_m();
    f.z_lo_m = z[static_cast<size_t>(h.elements.front())];
    f.z_hi_m = z[static_cast<size_t>(h.elements.back()) + 1];
    if (h.elements.size() == 1) return "element " + std::to_string(h.elements.front());
    std::string s = "elements";
    for (int e : h.elements) s += " " + std::to_string(e);
    return s;
  }
  if (h.kind == FaultKind::dry_run) return "";
  std::string s = "link";
  for (int i : h.links) s += " " + plant.links[static_cast<size_t>(i)].name;
  return s;
}

FrfData as_frf(const Values& v, const Aligned& a) {
  FrfData f;
  f.speed_rpm = a.speed_rpm;
  f.freq_hz = a.freq_hz;
  for (size_t e = 0; e < a.entries.size(); ++e) f.entries.push_back({a.entries[e].output, a.entries[e].input, v[e], {}, {}});
  return f;
}


std::vector<FaultEstimate> fit_plant_faults(const PlantModel& plant, const std::vector<FaultHypothesis>& hyps, ModelGrid& grid,
                                            const FrfFitTarget& target, const Aligned& a, const DiagnosisOptions& options,
                                            std::vector<Screened>& screened) {
  auto progress = [&](const std::string& stage, int done, int total) {
    if (options.progress) options.progress(stage, done, total);
  };
  // Screening: one evaluation per plant hypothesis (every crack element).
  int n_plant = 0;
  for (const auto& h : hyps) n_plant += is_plant_fault(h.kind);
  for (size_t i = 0; i < hyps.size(); ++i) {
    if (!is_plant_fault(hyps[i].kind)) continue;
    progress("screening fault models", static_cast<int>(screened.size()), n_plant);
    screened.push_back(screen(hyps[i], i, grid, target));
  }
  // Refine every non-crack hypothesis and the most promising crack elements.
  std::vector<const Screened*> cracks, chosen;
  for (const auto& s : screened) (hyps[s.id].kind == FaultKind::rotor_crack ? cracks : chosen).push_back(&s);
  // The secant overrates elements next to the cracked one when the probe is
  // far from the truth: evaluate each element at its linearised estimate
  // too, and rank by the lowest chi2 seen.
  int n_done = 0;
  for (auto& s : screened) {
    if (hyps[s.id].kind != FaultKind::rotor_crack) continue;
    progress("locating a crack", n_done++, static_cast<int>(cracks.size()));
    if (std::fabs(s.x_lin - hyps[s.id].nominal) > 1e-3) s.chi2 = std::min(s.chi2, fit_chi2(target, grid.evaluate(hyps[s.id], s.id, s.x_lin)));
  }
  std::sort(cracks.begin(), cracks.end(), [](const Screened* x, const Screened* y) { return x->chi2 < y->chi2; });
  for (size_t k = 0; k < cracks.size() && k < static_cast<size_t>(options.crack_refine); ++k) chosen.push_back(cracks[k]);

  std::vector<FaultEstimate> cands;
  int done = 0;
  for (const Screened* s : chosen) {
    const FaultHypothesis& h = hyps[s->id];
    progress("fitting fault models", done++, static_cast<int>(chosen.size()));
    const int before = grid.evaluations();
    const Fitted f = refine(h, *s, grid, target);
    FaultEstimate est;
    est.hypothesis = h;
    est.name = to_string(h.kind);
    est.location = location_of(h, plant, est);
    est.value = f.x;
    est.sd = f.sd;
    est.chi2 = f.chi2;
    est.coefficient_factor = link_coefficient_factor(h, f.x);
    est.nrmse = nrmse_of(grid.evaluate(h, s->id, f.x), a);  // the model itself, no bias correction
    est.evaluations = grid.evaluations() - before + 1;
    cands.push_back(est);
  }

  return cands;
}

std::vector<FaultEstimate> fit_channel_faults(const PlantModel& plant, const std::vector<FaultHypothesis>& hyps, const Aligned& a,
                                              const Values& pure_model, const FrfFitTarget& plain, double extra_chi2) {
  const size_t lines = a.freq_hz.size();
  const double n_values = static_cast<double>(a.values());
  Values healthy;  // the prediction of the healthy machine
  for (const auto& e : a.entries) healthy.push_back(e.mean);
  std::vector<FaultEstimate> cands;
  // Channel hypotheses: a gain on one row or column of the healthy
  // prediction, linear in the gain, so solved in closed form.
  for (const auto& h : hyps) {
    if (is_plant_fault(h.kind)) continue;
    const bool row = h.kind == FaultKind::sensor_fault;
    double num = 0.0, den = 0.0;
    for (size_t e = 0; e < a.entries.size(); ++e) {
      const auto& en = a.entries[e];
      if ((row ? en.output : en.input) != h.channel) continue;
      for (size_t l = 0; l < lines; ++l) {
        const double w2 = 1.0 / en.var[l];
        num += w2 * (std::conj(en.mean[l]) * en.h[l]).real();
        den += w2 * std::norm(en.mean[l]);
      }
    }
    if (den <= 0.0) continue;
    const double g = std::clamp(num / den, h.lower, h.upper);
    Values v = healthy, pure = pure_model;
    for (size_t e = 0; e < a.entries.size(); ++e) {
      if ((row ? a.entries[e].output : a.entries[e].input) != h.channel) continue;
      for (auto& x : v[e]) x *= g;
      for (auto& x : pure[e]) x *= g;
    }
    FaultEstimate est;
    est.hypothesis = h;
    est.name = to_string(h.kind);
    est.location = location_of(h, plant, est);
    est.value = g;
    est.chi2 = fit_chi2(plain, v) + extra_chi2;
    est.sd = std::sqrt(std::max(1.0, est.chi2 / n_values) / (2.0 * den));
    est.nrmse = nrmse_of(pure, a);
    cands.push_back(est);
  }

  return cands;
}

void rank_faults(std::vector<FaultEstimate> cands, const std::vector<FaultHypothesis>& hyps,
                 const std::vector<Screened>& screened, ModelGrid& grid, const Aligned& a, const DiagnosisOptions& options,
                 DiagnosisResult& res) {
  const double n_values = static_cast<double>(a.values());
  // Scores and ranking.
  const double n_real = 2.0 * n_values;
  double best_bic = std::numeric_limits<double>::infinity();
  for (auto& c : cands) {
    c.bic = 2.0 * c.chi2 + std::log(n_real) + 2.0 * std::log(std::max(1, c.hypothesis.alternatives));
    best_bic = std::min(best_bic, c.bic);
    c.ci_lo = std::max(c.hypothesis.lower, c.value - 1.96 * c.sd);
    c.ci_hi = std::min(c.hypothesis.upper, c.value + 1.96 * c.sd);
  }
  double wsum = 0.0;
  for (auto& c : cands) wsum += (c.score = std::exp(-0.5 * (c.bic - best_bic)));
  for (auto& c : cands) c.score /= wsum;
  std::sort(cands.begin(), cands.end(), [](const FaultEstimate& x, const FaultEstimate& y) { return x.bic < y.bic; });

  const FaultEstimate& best = cands.front();
  res.chi2_after = best.chi2;
  res.nrmse_after = best.nrmse;
  const double noise_floor = 0.5 * res.threshold;  // the detection threshold in complex-chi2 units
  // The healthy expectation of chi2 (N, or more with an estimated sigma).
  const double healthy_chi2 = 0.5 * a.t_mean();
  res.explained = best.chi2 <= noise_floor + options.unexplained_share * std::max(res.chi2_before - healthy_chi2, 0.0);
  // The best model's pure FRF for plots.
  if (is_plant_fault(best.hypothesis.kind)) {
    for (const auto& s : screened)
      if (hyps[s.id].kind == best.hypothesis.kind && hyps[s.id].elements == best.hypothesis.elements &&
          hyps[s.id].links == best.hypothesis.links)
        res.model_after = as_frf(grid.evaluate(hyps[s.id], s.id, best.value), a);
  } else {
    res.model_after = res.model_before;
    for (auto& e : res.model_after.entries)
      if ((best.hypothesis.kind == FaultKind::sensor_fault ? e.output : e.input) == best.hypothesis.channel)
        for (auto& x : e.h) x *= best.value;
  }
  res.faults = cands;
  if (!res.explained) {
    FaultEstimate unknown;
    unknown.name = "unknown";
    unknown.chi2 = res.chi2_before;
    unknown.score = 1.0;  // first, whatever the candidates' relative weights
    res.faults.insert(res.faults.begin(), unknown);
  }
}

}  // namespace ambdiag::diagnosis_detail
