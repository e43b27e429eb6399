#include "ambdiag/algorithms/identification/rational_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>

#include "ambdiag/core/error.h"
#include "fit_data.h"

namespace ambdiag {

using detail::cd;
using detail::FitData;

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
// An entry carries signal when its RMS exceeds this many noise RMS.
constexpr double kMinEntrySnr = 3.0;
// ... or when at least this share of its lines (and this many) exceed that
// many sigma: noise does so at a share exp(-9) = 1.2e-4 of the lines
// (complex Gaussian), 0.3 % even with sigma under-estimated by 20 %.
constexpr double kMinShareAbove = 0.01;
constexpr size_t kMinLinesAbove = 4;
// A delay is fitted when its score statistic (chi^2, 1 degree of freedom)
// exceeds this: 5 standard deviations.
constexpr double kMinDelayScore = 25.0;
// Poles added after the order search where the residual shows structure,
// and the significance (z of the residual chi^2 over a window) that
// triggers it.
constexpr int kMaxAddedPoles = 4;
constexpr double kMinWindowZ = 6.0;
// Above this chi^2 per degree of freedom the residual is not noise: sigma is
// scaled up by the local residual and the order searched again.
constexpr double kMaxConsistentChi2 = 1.3;
// A pole whose residue matrix (outputs x inputs) has a second singular
// value above this share of the first may hold two modes (a single mode's
// residue is rank one, psi l^T); it is tried as two poles (at most
// kMaxSplits times), and the split kept when its likelihood ratio exceeds
// the parameters it adds by kMinSplitZ standard deviations.
constexpr double kSplitRank = 0.3;
constexpr int kMaxSplits = 3;
constexpr double kMinSplitZ = 5.0;
constexpr int kSplitTrialIterations = 10;
// Close pairs refitted with modal residues: damping ratio below this, and
// at most this many LM iterations.
constexpr double kMaxPairZeta = 0.5;
constexpr int kPairIterations = 40;
// A pair whose modal refit fails the test with the other poles fixed, but
// by less than this factor of the allowed rise, gets up to kJointRounds
// rounds of the other poles refitted with the pair held.
constexpr double kMaxJointRise = 10.0;
constexpr int kJointRounds = 3;

int numerator_power(FrfQuantity q) {
  switch (q) {
    case FrfQuantity::compliance: return 0;
    case FrfQuantity::mobility: return 1;
    case FrfQuantity::accelerance: return 2;
  }
  return 0;
}

struct Prepared {
  FitData data;
  std::vector<int> entries;
  bool sigma_given = true;
  std::vector<size_t> lines;  // indices into frf.freq_hz
};

Prepared prepare(const FrfData& frf, const RationalFitOptions& opt, int power) {
  Prepared p;
  for (size_t l = 0; l < frf.freq_hz.size(); ++l) {
    const double f = frf.freq_hz[l];
    if ((opt.f_min_hz > 0 && f < opt.f_min_hz) || (opt.f_max_hz > 0 && f > opt.f_max_hz)) continue;
    p.lines.push_back(l);
  }
  if (p.lines.size() < 4) throw InputError("fit: fewer than 4 frequency lines in the band");
  p.sigma_given = std::all_of(frf.entries.begin(), frf.entries.end(), [](const FrfEntry& e) { return !e.sigma.empty(); });

  double max_rms = 0.0;
  std::vector<double> rms(frf.entries.size(), 0.0), noise(frf.entries.size(), 0.0);
  for (size_t e = 0; e < frf.entries.size(); ++e) {
    for (size_t l : p.lines) {
      rms[e] += std::norm(frf.entries[e].h[l]);
      if (p.sigma_given) noise[e] += frf.entries[e].sigma[l] * frf.entries[e].sigma[l];
    }
    rms[e] = std::sqrt(rms[e] / static_cast<double>(p.lines.size()));
    noise[e] = std::sqrt(noise[e] / static_cast<double>(p.lines.size()));
    max_rms = std::max(max_rms, rms[e]);
  }
  for (size_t e = 0; e < frf.entries.size(); ++e) {
    // With sigma, also an entry whose RMS is low but that rises clearly
    // above its noise at enough lines (resonances of a broadband accelerance
    // whose noise spans the whole band: the RMS criterion alone dropped 5 of
    // amrotor's 8 accelerometers, which show its modes at 6-14 sigma).
    size_t above = 0;
    if (p.sigma_given)
      for (size_t l : p.lines) above += std::abs(frf.entries[e].h[l]) > kMinEntrySnr * frf.entries[e].sigma[l] ? 1u : 0u;
    const bool peaks = above >= std::max<size_t>(kMinLinesAbove, static_cast<size_t>(kMinShareAbove * static_cast<double>(p.lines.size())));
    const bool signal = p.sigma_given ? rms[e] > kMinEntrySnr * noise[e] || peaks : rms[e] > 1e-6 * max_rms;
    if (signal) p.entries.push_back(static_cast<int>(e));
  }
  if (p.entries.empty()) throw InputError("fit: no FRF entry rises above its noise");

  const int L = static_cast<int>(p.lines.size()), E = static_cast<int>(p.entries.size());
  p.data.w.resize(L);
  p.data.h.resize(L, E);
  p.data.weight.resize(L, E);
  for (int i = 0; i < L; ++i) p.data.w(i) = kTwoPi * frf.freq_hz[p.lines[static_cast<size_t>(i)]];
  for (int k = 0; k < E; ++k) {
    const FrfEntry& en = frf.entries[static_cast<size_t>(p.entries[static_cast<size_t>(k)])];
    for (int i = 0; i < L; ++i) {
      const size_t l = p.lines[static_cast<size_t>(i)];
      const cd jw(0.0, p.data.w(i));
      const cd scale = power == 0 ? cd(1.0) : std::pow(jw, power);
      p.data.h(i, k) = en.h[l] / scale;
      // Without sigma: equal weight per line in the file's own quantity,
      // relative to the entry's RMS; the covariance is rescaled later.
      const double sigma = p.sigma_given ? en.sigma[l] : 1e-2 * rms[static_cast<size_t>(p.entries[static_cast<size_t>(k)])];
      if (!(sigma > 0)) throw InputError("fit: sigma of " + en.output + "/" + en.input + " is zero at line " + std::to_string(l));
      p.data.weight(i, k) = std::abs(scale) / sigma;
    }
  }
  return p;
}

// Principal responses of the weighted data for the order search: the poles
// are common, so a few dominant singular directions carry them all at a
// fraction of the cost. The weights are split as weight(l, e) ~ a(l) b(e)
// (a rank-one fit): b(e) scales the entries before they are combined, a(l)
// stays a line weight of the principal responses. Per-line weights matter:
// an accelerance divided by w^2 spans decades, and a per-entry weight alone
// would let the lowest lines dominate the search.
FitData compress(const FitData& d, int max_responses, int max_lines) {
  const int L = d.lines(), E = d.entries();
  Eigen::VectorXd b(E), a(L);
  for (int e = 0; e < E; ++e) b(e) = std::sqrt(d.weight.col(e).array().square().mean());
  for (int l = 0; l < L; ++l) a(l) = std::sqrt((d.weight.row(l).transpose().array() / b.array()).square().mean());
  const Eigen::MatrixXcd y = d.h * b.asDiagonal();
  // Every `step`-th line: the order search needs the shape of the
  // response, not every line; the final fits use all of them.
  const int step = std::max(1, L / max_lines);
  const int lk = (L + step - 1) / step;
  Eigen::VectorXd w(lk), wl(lk);
  Eigen::MatrixXcd ys(lk, E);
  for (int i = 0; i < lk; ++i) {
    w(i) = d.w(i * step);
    wl(i) = a(i * step);
    ys.row(i) = y.row(i * step);
  }
  const int r = std::min(E, max_responses);
  Eigen::MatrixXd v = Eigen::MatrixXd::Identity(E, E);
  if (E > max_responses) {
    // Real combinations only: a complex one would break the conjugate
    // symmetry H(-jw) = conj H(jw) that the real pole-residue basis relies on.
    const Eigen::MatrixXcd yw = wl.asDiagonal() * ys;
    const Eigen::MatrixXd gram = yw.real().transpose() * yw.real() + yw.imag().transpose() * yw.imag();
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(gram);
    v = es.eigenvectors().rightCols(r);
  }
  FitData out{w, ys * v, wl.replicate(1, r)};
  return out;
}

// Bayesian information criterion with the noise scale estimated from the
// residual: n log(cost / n) + p log n. Where sigma is right and the model
// complete (cost ~ n / 2) its differences between orders equal those of the
// known-sigma form 2 cost + p log n; where model error dominates (real
// data: the noise model is imperfect) a new pole pair must lower the cost by
// a fraction, not by a number of sigma^2, which stops the order growing to
// fit every systematic wiggle. The scale is floored at the given sigma
// (cost / n >= 1/2): a fit below the noise is not rewarded.
double criterion(double cost, int params, int n_real) {
  const double scale = std::max(cost / n_real, 0.5);
  return n_real * std::log(scale) + params * std::log(static_cast<double>(n_real));
}

// A lightly damped pole at the line where the fit with `poles` leaves the
// largest residual (summed over responses, smoothed over a few lines).
cd worst_fit_pole(const FitData& d, const std::vector<cd>& poles) {
  const detail::LinearSolution lin = detail::solve_residues(d, poles);
  Eigen::VectorXd misfit = Eigen::VectorXd::Zero(d.lines());
  for (int l = 0; l < d.lines(); ++l) {
    for (int e = 0; e < d.entries(); ++e) {
      cd m = lin.direct(e);
      for (size_t k = 0; k < poles.size(); ++k) {
        const cd r = lin.residues(e, static_cast<Eigen::Index>(k)), s(0.0, d.w(l));
        m += r / (s - poles[k]);
        if (poles[k].imag() != 0.0) m += std::conj(r) / (s - std::conj(poles[k]));
      }
      misfit(l) += std::norm(d.weight(l, e) * (m - d.h(l, e)));
    }
  }
  Eigen::Index at = 0;
  double best = -1.0;
  for (int l = 0; l < d.lines(); ++l) {
    double sum = 0.0;
    for (int k = std::max(0, l - 2); k <= std::min(d.lines() - 1, l + 2); ++k) sum += misfit(k);
    if (sum > best) {
      best = sum;
      at = l;
    }
  }
  const double w = d.w(at);
  return cd(-w / 50.0, w);
}

int model_parameters(const std::vector<cd>& poles, int entries) {
  return detail::basis_columns(poles) * (1 + entries) + entries;
}

std::vector<bool> stable_against(const std::vector<cd>& now, const std::vector<cd>& before) {
  std::vector<bool> out;
  for (const cd& p : now) {
    const double f = std::abs(p), z = -p.real() / std::abs(p);
    bool ok = false;
    for (const cd& q : before) {
      const double fq = std::abs(q), zq = -q.real() / std::abs(q);
      if (std::abs(f - fq) < 0.01 * f && std::abs(z - zq) < 0.05 * z + 0.002) ok = true;
    }
    out.push_back(ok);
  }
  return out;
}

// Order search on the principal responses, each order warm-started from
// the previous one plus one new pair where the model misfits most; the
// search stops 4 orders after the best criterion. Returns the best poles.
std::vector<cd> search_order(const FitData& data, const RationalFitOptions& opt, RationalFitResult& out) {
  const double w_min = data.w.minCoeff(), w_max = data.w.maxCoeff();
  const FitData small = compress(data, 6, 400);
  const int n_small = 2 * small.lines() * small.entries();
  std::vector<cd> prev, poles;
  out.stabilization.clear();
  double best = std::numeric_limits<double>::infinity();
  int since_best = 0;
  for (int n = 1; n <= opt.max_modes; ++n) {
    std::vector<cd> start = prev;
    start.push_back(n == 1 ? detail::starting_poles(1, w_min, w_max)[0] : worst_fit_pole(small, prev));
    while (detail::basis_columns(start) > 2 * n) start.erase(start.begin());
    const std::vector<cd> p = detail::vector_fit(small, start, n == 1 ? opt.vf_iterations : 4);
    const double cost = detail::solve_residues(small, p).cost;
    StabilizationRow row;
    row.modes = n;
    row.poles = p;
    row.stable = stable_against(p, prev);
    row.chi2_per_dof = 2.0 * cost / std::max(1, n_small - model_parameters(p, small.entries()));
    row.criterion = criterion(cost, model_parameters(p, small.entries()), n_small);
    out.stabilization.push_back(row);
    prev = p;
    if (row.criterion < best) {
      best = row.criterion;
      out.selected_modes = n;
      poles = p;
      since_best = 0;
    } else if (++since_best >= 4) {
      break;
    }
  }
  return poles;
}

// Orders of the stabilization diagram that hold a pole within 1 % in
// frequency and 25 % in damping of p (the ML pole moves a little from the
// search's).
int orders_holding(const std::vector<StabilizationRow>& rows, cd p) {
  const double f = std::abs(p), z = -p.real() / std::abs(p);
  int n = 0;
  for (const auto& row : rows) {
    for (const cd& q : row.poles) {
      if (q.imag() == 0.0) continue;
      const double fq = std::abs(q), zq = -q.real() / std::abs(q);
      if (std::abs(f - fq) < 0.01 * f && std::abs(z - zq) < 0.25 * z + 0.002) {
        ++n;
        break;
      }
    }
  }
  return n;
}

// Likelihood-ratio significance of pole k: the increase of the weighted
// cost when it is removed and the residues of the others refitted, as a
// chi^2 (2 x cost, re and im each carry half the variance). A pole that
// fits noise, or one of two poles splitting one resonance (the other
// absorbs it), costs little to remove; a mode seen weakly in many entries
// costs a lot even when no single entry shows it clearly.
double removal_chi2(const FitData& d, const std::vector<cd>& poles, size_t k, double cost) {
  std::vector<cd> rest = poles;
  rest.erase(rest.begin() + static_cast<long>(k));
  return 2.0 * (detail::solve_residues(d, rest).cost - cost);
}

// Weighted squared residuals |w (H_model - H)|^2 (1 on average where sigma
// is right), lines x entries.
Eigen::MatrixXd residual2(const FitData& d, const detail::MlSolution& ml) {
  const Eigen::MatrixXcd phi = detail::pole_basis(ml.poles, d.w, true);
  Eigen::MatrixXd q(d.lines(), d.entries());
  for (int e = 0; e < d.entries(); ++e) {
    for (int l = 0; l < d.lines(); ++l) {
      cd m = ml.linear.direct(e);
      for (size_t k = 0; k < ml.poles.size(); ++k) {
        const cd r = ml.linear.residues(e, static_cast<Eigen::Index>(k)), s(0.0, d.w(l));
        m += r / (s - ml.poles[k]);
        if (ml.poles[k].imag() != 0.0) m += std::conj(r) / (s - std::conj(ml.poles[k]));
      }
      q(l, e) = std::norm(d.weight(l, e) * (m - d.h(l, e)));
    }
  }
  return q;
}

// Local residual scale per line: the mean squared weighted residual over
// all entries and +-10 % in frequency (at least +-5 lines; wider than a
// resonance, so that a mode the first fit missed is not down-weighted),
// floored at 1.
Eigen::VectorXd local_misfit(const FitData& d, const detail::MlSolution& ml) {
  const Eigen::VectorXd per_line = residual2(d, ml).rowwise().mean();
  const int L = d.lines();
  Eigen::VectorXd c(L);
  for (int l = 0; l < L; ++l) {
    int lo = l, hi = l;
    while (lo > 0 && (d.w(l) - d.w(lo - 1) <= 0.1 * d.w(l) || l - lo < 5)) --lo;
    while (hi < L - 1 && (d.w(hi + 1) - d.w(l) <= 0.1 * d.w(l) || hi - l < 5)) ++hi;
    c(l) = std::max(1.0, per_line.segment(lo, hi - lo + 1).mean());
  }
  return c;
}

// Centre (rad/s) of the window of +-1 % in frequency (at least +-2 lines)
// where one entry's weighted residual is most significantly above the noise
// (z of its chi^2 over the window above 6, the noise scaled by `scale2`);
// 0 when there is none.
double worst_window(const FitData& d, const detail::MlSolution& ml, double scale2) {
  const int L = d.lines(), E = d.entries();
  const Eigen::MatrixXd q = 2.0 * residual2(d, ml) / scale2;  // chi^2 per line (2 degrees of freedom)
  double best_z = kMinWindowZ, best_w = 0.0;
  for (int l = 0; l < L; ++l) {
    int lo = l, hi = l;
    while (lo > 0 && (d.w(l) - d.w(lo - 1) <= 0.01 * d.w(l) || l - lo < 2)) --lo;
    while (hi < L - 1 && (d.w(hi + 1) - d.w(l) <= 0.01 * d.w(l) || hi - l < 2)) ++hi;
    const int m = hi - lo + 1;
    // Per entry, and over all entries (a mode seen weakly in many).
    double all = 0.0;
    for (int e = 0; e < E; ++e) {
      const double sum = q.col(e).segment(lo, m).sum();
      all += sum;
      const double z = (sum - 2.0 * m) / (2.0 * std::sqrt(static_cast<double>(m)));
      if (z > best_z) {
        best_z = z;
        best_w = d.w(l);
      }
    }
    const double z_all = (all - 2.0 * m * E) / (2.0 * std::sqrt(static_cast<double>(m) * E));
    if (z_all > best_z) {
      best_z = z_all;
      best_w = d.w(l);
    }
  }
  return best_w;
}

// Which output and input each fitted entry connects.
detail::ModalStructure modal_structure(const FrfData& frf, const std::vector<int>& entries) {
  std::map<std::string, int> outs, ins;
  detail::ModalStructure m;
  for (int e : entries) {
    const FrfEntry& en = frf.entries[static_cast<size_t>(e)];
    m.output_of.push_back(outs.emplace(en.output, static_cast<int>(outs.size())).first->second);
    m.input_of.push_back(ins.emplace(en.input, static_cast<int>(ins.size())).first->second);
  }
  m.outputs = static_cast<int>(outs.size());
  m.inputs = static_cast<int>(ins.size());
  return m;
}

// Second over first singular value of each pole's residue matrix, the
// entries placed at their (output, input); entries without signal are 0.
std::vector<double> residue_rank_ratio(const detail::ModalStructure& modal, const Eigen::MatrixXcd& residues) {
  std::vector<double> ratio;
  for (Eigen::Index k = 0; k < residues.cols(); ++k) {
    Eigen::MatrixXcd r = Eigen::MatrixXcd::Zero(modal.outputs, modal.inputs);
    for (size_t i = 0; i < modal.output_of.size(); ++i) r(modal.output_of[i], modal.input_of[i]) = residues(static_cast<Eigen::Index>(i), k);
    const Eigen::VectorXd s = Eigen::JacobiSVD<Eigen::MatrixXcd>(r).singularValues();
    ratio.push_back(s.size() > 1 && s(0) > 0 ? s(1) / s(0) : 0.0);
  }
  return ratio;
}

// Close pairs with modal residues. With free residues per entry, two poles
// whose half-power bands overlap (a heavily damped whirl pair a few percent
// apart) are poorly determined along their separation: each entry can trade
// one pole's residue for the other's. A single mode's residue matrix is
// rank one, psi l^T, which ties the entries together (per pole 2 (outputs +
// inputs - 1) real parameters instead of 2 entries). Each such pair is
// refitted with modal residues (the other poles fixed) and the constrained
// poles are kept when the likelihood ratio does not reject the constraint:
// chi^2 rises by less than the removed parameters plus kMinSplitZ standard
// deviations. A repeated root (x/y housing modes: rank two) is rejected.
// The other poles were placed by the free fit, around the pair's free
// residues; when the test fails with them fixed (by less than
// kMaxJointRise x the allowed rise), they are refitted with the pair's
// modal contribution held and the pair refitted again (up to kJointRounds
// rounds, poles of pairs accepted before held too).
void refit_close_pairs(const FrfData& frf, const std::vector<int>& entries, const FitData& undelayed_data, double noise_scale2,
                       detail::MlSolution& ml) {
  const detail::ModalStructure modal = modal_structure(frf, entries);
  const int removed = 2 * (2 * undelayed_data.entries() - 2 * (modal.outputs + modal.inputs - 1));
  if (removed <= 0) return;
  const double allowed = removed + kMinSplitZ * std::sqrt(2.0 * removed);
  const double w_min = undelayed_data.w.minCoeff(), w_max = undelayed_data.w.maxCoeff();
  std::vector<size_t> order;
  for (size_t k = 0; k < ml.poles.size(); ++k) {
    const cd p = ml.poles[k];
    if (p.imag() > 0.0 && p.imag() >= 0.9 * w_min && p.imag() <= 1.05 * w_max && -p.real() < kMaxPairZeta * std::abs(p)) order.push_back(k);
  }
  std::sort(order.begin(), order.end(), [&](size_t x, size_t y) { return ml.poles[x].imag() < ml.poles[y].imag(); });
  std::vector<int> col(ml.poles.size(), 0);
  for (size_t k = 1; k < ml.poles.size(); ++k) col[k] = col[k - 1] + (ml.poles[k - 1].imag() == 0.0 ? 1 : 2);
  std::vector<bool> constrained(ml.poles.size(), false);  // poles of accepted pairs: held in later joint rounds
  for (size_t n = 0; n + 1 < order.size(); ++n) {
    const size_t k1 = order[n], k2 = order[n + 1];
    const cd p1 = ml.poles[k1], p2 = ml.poles[k2];
    if (!(p2.imag() - p1.imag() < -p1.real() - p2.real())) continue;
    detail::PairRefit r = detail::refit_pair_rank_one(undelayed_data, ml.poles, ml.linear.residues, k1, k2, modal, kPairIterations);
    double rise = 2.0 * (r.cost - ml.linear.cost) / noise_scale2;
    // The other poles were placed by the free fit, whose pair residues
    // also absorbed part of their misfit. When the constraint does not pass
    // with them fixed, but is not far off, refit them with the pair's
    // modal contribution held (block coordinate descent on the joint
    // constrained likelihood), then the pair again.
    std::vector<cd> poles = ml.poles;
    Eigen::MatrixXd others_cov;
    for (int round = 0; round < kJointRounds && r.ok && !(rise < allowed) && rise < kMaxJointRise * allowed; ++round) {
      detail::FitData rest = undelayed_data;
      const Eigen::MatrixXcd pair_basis = detail::pole_basis({r.poles[0], r.poles[1]}, rest.w, false);
      for (int e = 0; e < rest.entries(); ++e)
        for (int m = 0; m < 2; ++m)
          rest.h.col(e) -= r.residues(e, m).real() * pair_basis.col(2 * m) + r.residues(e, m).imag() * pair_basis.col(2 * m + 1);
      std::vector<cd> others;
      std::vector<bool> held;
      for (size_t k = 0; k < poles.size(); ++k)
        if (k != k1 && k != k2) {
          others.push_back(poles[k]);
          held.push_back(constrained[k]);
        }
      const detail::MlSolution mo = detail::ml_refine(rest, others, kPairIterations, false, 0.0, held);
      std::vector<cd> trial;
      for (size_t k = 0, o = 0; k < poles.size(); ++k) trial.push_back(k == k1 ? r.poles[0] : k == k2 ? r.poles[1] : mo.poles[o++]);
      const detail::PairRefit r2 = detail::refit_pair_rank_one(undelayed_data, trial, detail::solve_residues(undelayed_data, trial).residues, k1, k2, modal, kPairIterations);
      if (!r2.ok || !(r2.cost < r.cost)) break;
      r = r2;
      trial[k1] = r.poles[0];
      trial[k2] = r.poles[1];
      poles = trial;
      others_cov = mo.pole_covariance;
      rise = 2.0 * (r.cost - ml.linear.cost) / noise_scale2;
    }
    if (!r.ok || !(rise < allowed)) continue;
    if (others_cov.size() > 0) {
      // Covariance of the other poles conditional on the pair, like the
      // pair's conditional on them (poles held in the rounds keep theirs).
      Eigen::Index oc = 0;
      for (size_t k = 0; k < poles.size(); ++k) {
        if (k == k1 || k == k2) continue;
        const int n_k = poles[k].imag() == 0.0 ? 1 : 2;
        if (!constrained[k]) ml.pole_covariance.block(col[k], col[k], n_k, n_k) = others_cov.block(oc, oc, n_k, n_k);
        oc += n_k;
      }
    }
    ml.poles = poles;
    ml.poles[k1] = r.poles[0];
    ml.poles[k2] = r.poles[1];
    ml.linear = detail::solve_residues(undelayed_data, ml.poles);
    ml.pole_covariance.block(col[k1], col[k1], 2, 2) = r.covariance.topLeftCorner(2, 2);
    ml.pole_covariance.block(col[k2], col[k2], 2, 2) = r.covariance.bottomRightCorner(2, 2);
    constrained[k1] = constrained[k2] = true;
    ++n;  // each pole in one pair
  }
}

}  // namespace

std::complex<double> RationalModel::evaluate(int entry, double w) const {
  const cd s(0.0, w);
  cd h = direct(entry);
  for (size_t k = 0; k < poles.size(); ++k) {
    const cd r = residues(entry, static_cast<Eigen::Index>(k));
    h += r / (s - poles[k]);
    if (poles[k].imag() != 0.0) h += std::conj(r) / (s - std::conj(poles[k]));
  }
  return delay_s == 0.0 ? h : h * std::polar(1.0, -w * delay_s);
}

int RationalModel::pair_count() const {
  return static_cast<int>(std::count_if(poles.begin(), poles.end(), [](const cd& p) { return p.imag() != 0.0; }));
}

int RationalModel::real_parameter_count() const {
  return model_parameters(poles, static_cast<int>(direct.size()));
}

bool RationalFitOptions::is_valid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (f_min_hz < 0 || f_max_hz < 0 || (f_max_hz > 0 && f_max_hz <= f_min_hz)) return fail("band: need 0 <= fmin < fmax");
  if (modes < 0 || modes > 200) return fail("modes: must be in 0..200");
  if (max_modes < 1 || max_modes > 200) return fail("max_modes: must be in 1..200");
  if (vf_iterations < 1 || ml_iterations < 0) return fail("iterations: must be positive");
  return true;
}

RationalFitResult fit_rational(const FrfData& frf, const RationalFitOptions& opt) {
  std::string why;
  if (!opt.is_valid(&why)) throw InputError("fit options: " + why);
  RationalFitResult out;
  out.numerator_power = numerator_power(frf.quantity);
  const Prepared prep = prepare(frf, opt, out.numerator_power);
  FitData data = prep.data;  // weights may be lowered where model error dominates
  out.entries = prep.entries;
  const int n_real = 2 * data.lines() * data.entries();
  const double w_min = data.w.minCoeff(), w_max = data.w.maxCoeff();

  std::vector<cd> poles;
  if (opt.modes > 0) {
    poles = detail::vector_fit(data, detail::starting_poles(opt.modes, w_min, w_max), opt.vf_iterations);
    out.selected_modes = opt.modes;
  } else {
    poles = search_order(data, opt, out);
  }
  out.report.data_points = n_real;
  out.report.cost_start = detail::solve_residues(data, poles).cost;

  const int ml_iterations = opt.ml_refine ? opt.ml_iterations : 0;
  detail::MlSolution ml = detail::ml_refine(data, poles, ml_iterations);
  auto chi2 = [&](const detail::MlSolution& m) {
    const int params = model_parameters(m.poles, data.entries()) + (m.delay_sd_s > 0 ? 1 : 0);
    return 2.0 * m.linear.cost / std::max(1, n_real - params);
  };
  if (opt.estimate_delay && ml_iterations > 0) {
    // A pure delay e^{-j w tau} (acquisition) is not rational: unmodelled,
    // it is absorbed by spurious poles. Score test at tau = 0, in units of
    // the robust noise scale; when significant, fit the delay, search the
    // order again on the undelayed data and refine poles and delay jointly.
    const double score = detail::delay_score(data, ml.poles, 0.0) / std::max(1.0, chi2(ml));
    if (score > kMinDelayScore) {
      const detail::MlSolution first = detail::ml_refine(data, ml.poles, ml_iterations, true, 0.0);
      const std::vector<StabilizationRow> rows_without = out.stabilization;
      const int selected_without = out.selected_modes;
      std::vector<cd> p2 = first.poles;
      if (opt.modes == 0) p2 = search_order(detail::undelayed(data, first.delay_s), opt, out);
      detail::MlSolution with = detail::ml_refine(data, p2, ml_iterations, true, first.delay_s);
      // Kept when better by the same criterion as the orders (the delay
      // model may have fewer poles and a slightly higher cost).
      const auto crit = [&](const detail::MlSolution& m, int extra) {
        return criterion(m.linear.cost, model_parameters(m.poles, data.entries()) + extra, n_real);
      };
      if (crit(with, 1) < crit(ml, 0)) {
        ml = std::move(with);
      } else {
        out.stabilization = rows_without;
        out.selected_modes = selected_without;
      }
    }
  }
  if (opt.modes == 0 && ml_iterations > 0 && chi2(ml) > kMaxConsistentChi2) {
    // The residual exceeds the noise: sigma is under-estimated or the data
    // hold what no rational model of this order holds (real data). Left as
    // is, the search spends its poles where the misfit is largest rather than
    // on resonances. Scale sigma per line by the local residual (a floor of
    // the noise from the fit itself) and search again.
    const Eigen::VectorXd c = local_misfit(detail::undelayed(data, ml.delay_s), ml);
    for (int l = 0; l < data.lines(); ++l) data.weight.row(l) /= std::sqrt(c(l));
    out.report.sigma_inflated = true;
    std::vector<cd> p2 = search_order(detail::undelayed(data, ml.delay_s), opt, out);
    ml = detail::ml_refine(data, p2, ml_iterations, ml.delay_sd_s > 0, ml.delay_s);
  }
  if (opt.modes == 0 && ml_iterations > 0) {
    // The order search sees principal responses only: a mode in few or
    // weak entries (an axial mode, a weak mode next to a strong one) can be
    // missed. Where an entry's residual is significantly above the noise over
    // a resonance-wide window, add a pole there and keep it if the criterion
    // improves.
    const auto crit = [&](const detail::MlSolution& m) {
      return criterion(m.linear.cost, model_parameters(m.poles, data.entries()) + (m.delay_sd_s > 0 ? 1 : 0), n_real);
    };
    for (int extra = 0; extra < kMaxAddedPoles; ++extra) {
      const detail::FitData undelayed_data = detail::undelayed(data, ml.delay_s);
      const double w_new = worst_window(undelayed_data, ml, std::max(1.0, chi2(ml)));
      if (w_new <= 0.0) break;
      std::vector<cd> trial = ml.poles;
      trial.emplace_back(-0.02 * w_new, w_new);
      detail::MlSolution more = detail::ml_refine(data, trial, ml_iterations, ml.delay_sd_s > 0, ml.delay_s);
      if (!(crit(more) < crit(ml))) break;
      ml = std::move(more);
      ++out.selected_modes;
    }
  }
  // Poles that came from an accepted split, and the likelihood ratio that
  // accepted them: their significance is judged by that same test.
  std::vector<bool> split_born(ml.poles.size(), false);
  const int split_added = 2 + 2 * data.entries();
  const double split_needed = split_added + kMinSplitZ * std::sqrt(2.0 * split_added);
  if (opt.modes == 0 && ml_iterations > 0) {
    // Close modes merged into one pole (a rotor mode a few percent from a
    // housing mode, a whirl pair): the residual of the merged fit can sit at
    // the noise (the neighbours absorb the rest) and a new pair costs more
    // than the order criterion allows with many entries, yet the merged
    // pole's residue matrix is far from rank one. Such a pole is tried as
    // two, half a bandwidth apart, and the split is kept when the
    // likelihood ratio (chi^2, in noise units) exceeds the added parameters
    // by kMinSplitZ standard deviations (chi^2 with p dof: p + z sqrt(2p)).
    // A SISO fit has rank-one residues and never splits.
    const std::vector<double> ratio = residue_rank_ratio(modal_structure(frf, prep.entries), ml.linear.residues);
    std::vector<size_t> order;
    for (size_t k = 0; k < ml.poles.size(); ++k) {
      const cd p = ml.poles[k];
      if (p.imag() > 0.0 && p.imag() >= 0.9 * w_min && p.imag() <= 1.05 * w_max && -p.real() < p.imag() && ratio[k] > kSplitRank)
        order.push_back(k);
    }
    std::sort(order.begin(), order.end(), [&](size_t x, size_t y) { return ratio[x] > ratio[y]; });
    if (order.size() > static_cast<size_t>(kMaxSplits)) order.resize(kMaxSplits);
    std::vector<cd> candidates;
    for (size_t k : order) candidates.push_back(ml.poles[k]);
    for (const cd& p : candidates) {
      const auto at = std::find(ml.poles.begin(), ml.poles.end(), p);
      if (at == ml.poles.end()) continue;
      const double delta = std::max(0.01, -p.real() / std::abs(p));
      std::vector<cd> trial = ml.poles;
      trial[static_cast<size_t>(at - ml.poles.begin())] = p * (1.0 - delta);
      trial.push_back(p * (1.0 + delta));
      // A short trial first (most splits that fail, fail at once), the
      // full refinement only when it already passes the test.
      detail::MlSolution more = detail::ml_refine(data, trial, std::min(ml_iterations, kSplitTrialIterations), ml.delay_sd_s > 0, ml.delay_s);
      const double drop = 2.0 * (ml.linear.cost - more.linear.cost) / std::max(1.0, chi2(ml));
      if (!(drop > split_needed)) continue;
      if (!more.converged) more = detail::ml_refine(data, more.poles, ml_iterations, ml.delay_sd_s > 0, more.delay_s);
      split_born[static_cast<size_t>(at - ml.poles.begin())] = true;
      split_born.push_back(true);
      ml = std::move(more);
      ++out.selected_modes;
    }
  }
  if (opt.modes == 0 && ml_iterations > 0) refit_close_pairs(frf, prep.entries, detail::undelayed(data, ml.delay_s), std::max(1.0, chi2(ml)), ml);
  out.model.poles = ml.poles;
  out.model.residues = ml.linear.residues;
  out.model.direct = ml.linear.direct;
  out.model.delay_s = ml.delay_s;
  out.report.delay_s = ml.delay_s;
  out.report.delay_sd_s = ml.delay_sd_s;
  out.report.delay_fitted = ml.delay_sd_s > 0;
  out.report.cost = ml.linear.cost;
  out.report.ml_iterations = ml.iterations;
  out.report.converged = ml.converged || !opt.ml_refine;
  out.report.stop_reason = ml.stop_reason;
  out.report.chi2_per_dof = chi2(ml);
  out.report.sigma_from_data = prep.sigma_given;
  const FitData fitted = detail::undelayed(data, ml.delay_s);

  // Covariance of the pole parameters: Fisher information 2 J^T J (re and
  // im of each weighted residual have variance 1/2); without sigma, scale
  // by the residual variance.
  const double scale = 0.5 * (prep.sigma_given ? 1.0 : out.report.chi2_per_dof);
  // Squared weighted residuals (1 on average where sigma is right), and per
  // entry their robust scale: median / ln 2 (the median of an exponential
  // variable of mean 1), insensitive to a few misfit regions.
  const int E = data.entries();
  Eigen::MatrixXd resid2(data.lines(), E);
  for (int l = 0; l < data.lines(); ++l)
    for (int e = 0; e < E; ++e)
      resid2(l, e) = std::norm(fitted.weight(l, e) * (out.model.evaluate(e, fitted.w(l)) * std::polar(1.0, fitted.w(l) * ml.delay_s) - fitted.h(l, e)));
  Eigen::VectorXd entry_scale2(E);
  for (int e = 0; e < E; ++e) {
    std::vector<double> v(resid2.col(e).data(), resid2.col(e).data() + data.lines());
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    entry_scale2(e) = v[v.size() / 2] / std::log(2.0);
  }
  const double line_spacing = (w_max - w_min) / std::max(1, data.lines() - 1);
  const double noise_scale2 = prep.sigma_given ? std::max(1.0, out.report.chi2_per_dof) : out.report.chi2_per_dof;
  int col = 0;
  for (size_t k = 0; k < ml.poles.size(); ++k) {
    const cd p = ml.poles[k];
    if (p.imag() == 0.0) {
      ++col;
      continue;  // real poles: overdamped, not reported as modes
    }
    const double a = p.real(), b = p.imag(), mag = std::abs(p);
    IdentifiedMode m;
    m.pole = p;
    m.pole_index = static_cast<int>(k);
    m.f_hz = mag / kTwoPi;
    m.zeta = -a / mag;
    const Eigen::Matrix2d cov = scale * ml.pole_covariance.block(col, col, 2, 2);
    const Eigen::Vector2d gf(a / (kTwoPi * mag), b / (kTwoPi * mag));
    const Eigen::Vector2d gz(-b * b / (mag * mag * mag), a * b / (mag * mag * mag));
    m.f_sd_hz = std::sqrt(std::max(0.0, gf.dot(cov * gf)));
    m.zeta_sd = std::sqrt(std::max(0.0, gz.dot(cov * gz)));
    col += 2;
    // Peak of the mode's contribution over the noise, per entry, the noise
    // scaled by the robust residual scale of that entry (model error counts
    // as noise where it exceeds sigma).
    double total = 0.0;
    m.entry_weight.resize(static_cast<size_t>(E));
    Eigen::Index nearest = 0;
    (data.w.array() - b).abs().minCoeff(&nearest);
    const double half_band = std::max(std::abs(a), 2.0 * line_spacing);
    for (int e = 0; e < E; ++e) {
      const double peak = std::abs(out.model.residues(e, static_cast<Eigen::Index>(k))) / std::abs(a);
      double local = 0.0;
      int n_local = 0;
      for (int l = 0; l < data.lines(); ++l) {
        if (std::abs(data.w(l) - b) > half_band) continue;
        local += resid2(l, e);
        ++n_local;
      }
      // Without sigma the residual is the only noise estimate (no floor).
      const double floor2 = prep.sigma_given ? 1.0 : 1e-300;
      const double scale2 = std::max({floor2, entry_scale2(e), n_local > 0 ? local / n_local : 0.0});
      m.entry_weight[static_cast<size_t>(e)] = peak * data.weight(nearest, e);
      m.peak_snr = std::max(m.peak_snr, peak * data.weight(nearest, e) / std::sqrt(scale2));
      total += m.entry_weight[static_cast<size_t>(e)];
    }
    for (auto& wgt : m.entry_weight) wgt = total > 0 ? wgt / total : 0.0;
    m.stable_orders = orders_holding(out.stabilization, p);
    // Physical: in the band, and significant by the information criterion
    // of the order search (its pole and residues must pay for themselves),
    // the noise scaled by the residual where model error exceeds sigma.
    const bool in_band = b >= 0.9 * w_min && b <= 1.05 * w_max;
    if (!in_band || m.zeta >= 1.0) continue;
    m.significance = removal_chi2(fitted, ml.poles, k, ml.linear.cost) / noise_scale2;
    const double price = (2.0 + 2.0 * E) * std::log(static_cast<double>(n_real));
    if (m.significance > (k < split_born.size() && split_born[k] ? std::min(price, split_needed) : price)) out.modes.push_back(m);
  }
  std::sort(out.modes.begin(), out.modes.end(), [](const IdentifiedMode& x, const IdentifiedMode& y) { return x.f_hz < y.f_hz; });
  return out;
}

}  // namespace ambdiag
