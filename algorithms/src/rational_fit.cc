#include "ambdiag/algorithms/rational_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
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
// A pole is a physical mode when its resonance peak exceeds this many sigma.
constexpr double kMinModeSnr = 5.0;

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
    const bool signal = p.sigma_given ? rms[e] > kMinEntrySnr * noise[e] : rms[e] > 1e-6 * max_rms;
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

// Principal responses of the weighted data (per-entry scalar weights) for
// the order search: the poles are common, so a few dominant singular
// directions carry them all at a fraction of the cost.
FitData compress(const FitData& d, int max_responses, int max_lines) {
  const int L = d.lines(), E = d.entries();
  Eigen::VectorXd w_entry(E);
  for (int e = 0; e < E; ++e) w_entry(e) = std::sqrt(d.weight.col(e).array().square().mean());
  const Eigen::MatrixXcd y = d.h * w_entry.asDiagonal();
  // Every `step`-th line: the order search needs the shape of the
  // response, not every line; the final fits use all of them.
  const int step = std::max(1, L / max_lines);
  const int lk = (L + step - 1) / step;
  Eigen::VectorXd w(lk);
  Eigen::MatrixXcd ys(lk, E);
  for (int i = 0; i < lk; ++i) {
    w(i) = d.w(i * step);
    ys.row(i) = y.row(i * step);
  }
  if (E <= max_responses) {
    FitData out{w, ys, Eigen::MatrixXd::Ones(lk, E)};
    return out;
  }
  // Real combinations only: a complex one would break the conjugate symmetry
  // H(-jw) = conj H(jw) that the real pole-residue basis relies on.
  const Eigen::MatrixXd gram = (y.real().transpose() * y.real() + y.imag().transpose() * y.imag());
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(gram);
  const int r = max_responses;
  const Eigen::MatrixXd v = es.eigenvectors().rightCols(r);
  FitData out{w, ys * v, Eigen::MatrixXd::Ones(lk, r)};
  return out;
}

double criterion(double cost, int params, int n_real, bool sigma_given) {
  // Bayesian information criterion: -2 log likelihood + p log N. With known
  // sigma, -2 log L = 2 cost (re and im each carry sigma^2 / 2).
  const double fit = sigma_given ? 2.0 * cost : n_real * std::log(std::max(cost, 1e-300) / n_real);
  return fit + params * std::log(static_cast<double>(n_real));
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

}  // namespace

std::complex<double> RationalModel::evaluate(int entry, double w) const {
  const cd s(0.0, w);
  cd h = direct(entry);
  for (size_t k = 0; k < poles.size(); ++k) {
    const cd r = residues(entry, static_cast<Eigen::Index>(k));
    h += r / (s - poles[k]);
    if (poles[k].imag() != 0.0) h += std::conj(r) / (s - std::conj(poles[k]));
  }
  return h;
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
  const FitData& data = prep.data;
  out.entries = prep.entries;
  const int n_real = 2 * data.lines() * data.entries();
  const double w_min = data.w.minCoeff(), w_max = data.w.maxCoeff();

  std::vector<cd> poles;
  if (opt.modes > 0) {
    poles = detail::vector_fit(data, detail::starting_poles(opt.modes, w_min, w_max), opt.vf_iterations);
    out.selected_modes = opt.modes;
  } else {
    // Order search on the principal responses, each order warm-started
    // from the previous one plus one new pair.
    const FitData small = compress(data, 6, 400);
    const int n_small = 2 * small.lines() * small.entries();
    std::vector<cd> prev;
    double best = std::numeric_limits<double>::infinity();
    int since_best = 0;
    for (int n = 1; n <= opt.max_modes; ++n) {
      std::vector<cd> start = prev;
      // The new pair goes where the current model misfits most.
      start.push_back(n == 1 ? detail::starting_poles(1, w_min, w_max)[0] : worst_fit_pole(small, prev));
      while (detail::basis_columns(start) > 2 * n) start.erase(start.begin());
      const std::vector<cd> p = detail::vector_fit(small, start, n == 1 ? opt.vf_iterations : 4);
      const double cost = detail::solve_residues(small, p).cost;
      StabilizationRow row;
      row.modes = n;
      row.poles = p;
      row.stable = stable_against(p, prev);
      row.chi2_per_dof = 2.0 * cost / std::max(1, n_small - model_parameters(p, small.entries()));
      row.criterion = criterion(cost, model_parameters(p, small.entries()), n_small, true);
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
  }
  out.report.data_points = n_real;
  out.report.cost_start = detail::solve_residues(data, poles).cost;

  detail::MlSolution ml;
  if (opt.ml_refine && opt.ml_iterations > 0) {
    ml = detail::ml_refine(data, poles, opt.ml_iterations);
  } else {
    ml = detail::ml_refine(data, poles, 0);
  }
  out.model.poles = ml.poles;
  out.model.residues = ml.linear.residues;
  out.model.direct = ml.linear.direct;
  out.report.cost = ml.linear.cost;
  out.report.ml_iterations = ml.iterations;
  out.report.converged = ml.converged || !opt.ml_refine;
  out.report.stop_reason = ml.stop_reason;
  const int dof = std::max(1, n_real - out.model.real_parameter_count());
  out.report.chi2_per_dof = 2.0 * ml.linear.cost / dof;
  out.report.sigma_from_data = prep.sigma_given;

  // Covariance of the pole parameters: Fisher information 2 J^T J (re and
  // im of each weighted residual have variance 1/2); without sigma, scale
  // by the residual variance.
  const double scale = 0.5 * (prep.sigma_given ? 1.0 : out.report.chi2_per_dof);
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
    // Peak of the mode's contribution over the noise, per entry.
    double total = 0.0;
    m.entry_weight.resize(static_cast<size_t>(data.entries()));
    Eigen::Index nearest = 0;
    (data.w.array() - b).abs().minCoeff(&nearest);
    for (int e = 0; e < data.entries(); ++e) {
      const double peak = std::abs(out.model.residues(e, static_cast<Eigen::Index>(k))) / std::abs(a);
      m.entry_weight[static_cast<size_t>(e)] = peak * data.weight(nearest, e);
      m.peak_snr = std::max(m.peak_snr, peak * data.weight(nearest, e) * (prep.sigma_given ? 1.0 : 1.0 / std::sqrt(out.report.chi2_per_dof)));
      total += m.entry_weight[static_cast<size_t>(e)];
    }
    for (auto& wgt : m.entry_weight) wgt = total > 0 ? wgt / total : 0.0;
    const bool in_band = b >= 0.9 * w_min && b <= 1.05 * w_max;
    if (in_band && m.peak_snr >= kMinModeSnr && m.zeta < 1.0) out.modes.push_back(m);
  }
  std::sort(out.modes.begin(), out.modes.end(), [](const IdentifiedMode& x, const IdentifiedMode& y) { return x.f_hz < y.f_hz; });
  return out;
}

}  // namespace ambdiag
