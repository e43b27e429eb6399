// Multisine runs: per segment, the settle periods dropped, the DFT of every
// remaining period averaged at the excited bins; one experiment per segment;
// H per line from (1) of frf_estimation.h, sigma by (2) from the
// period-to-period covariance of [x; f]. The noise does not depend on the
// phase pattern (measurement noise, or process noise through a linear loop),
// so the covariance is pooled over the segments: sum (M_k - 1) degrees of
// freedom instead of M_k - 1 each, which keeps 1 / sigma^2 nearly unbiased.
// The rotor's synchronous response (1x-3x the run's speed), not periodic
// with the excitation, is fitted out of the measured channels first
// (struct Synchronous).
#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <numeric>
#include <string>
#include <vector>

#include <unsupported/Eigen/FFT>

#include "ambdiag/core/error.h"
#include "frf_estimation_internal.h"

namespace ambdiag {

using frf_estimation::ChannelPlan;
using frf_estimation::Experiment;

namespace {

// Reference power below this fraction of the strongest line: not excited.
constexpr double kExcitedPowerFraction = 1e-8;
// A segment whose reference power is below this fraction of the strongest
// segment's carries no excitation (a dropout).
constexpr double kDeadSegmentFraction = 1e-6;
// Fewer degrees of freedom of the noise covariance than this: sigma is
// itself too uncertain to trust without a warning.
constexpr long kFewDegreesOfFreedom = 4;
// Harmonics of the running speed removed from the measured channels (1x
// unbalance, 2x misalignment, 3x); a harmonic with less than this share of
// its energy outside the excitation-periodic signals is on the grid.
constexpr int kSynchronousHarmonics = 3;
constexpr double kSynchronousMinShare = 0.05;
constexpr double kSynchronousFitShare = 1e-8;

struct SegmentSpectra {
  size_t index = 0;
  long periods = 0;                      // usable
  std::vector<Eigen::VectorXcd> z_mean;  // per bin: outputs then inputs
  std::vector<Eigen::VectorXcd> r_mean;  // per bin: references
  std::vector<Eigen::MatrixXcd> z_ss;    // per bin: sum over periods of (z_p - mean)(z_p - mean)^H
  std::vector<double> lost_dof;          // per bin: complex degrees of freedom the synchronous fit took
  double reference_power = 0.0;
};

// The rotor's synchronous response in a segment's window of m periods:
// the harmonics h f1 (f1 in cycles per sample, h = 1..kSynchronousHarmonics)
// that are not periodic with the excitation, fitted by least squares of
// x = periodic + S c. Only the sinusoids' part orthogonal to every periodic
// signal (each minus its period average), O, tells them apart: c = (O^T
// O)^-1 O^T x, and x - S c leaves the periodic part and the scatter. That
// fit also takes noise out of the scatter, at the bins where O lives:
// lost[b] complex degrees of freedom at bin b (sum over bins: one per
// sinusoid). A harmonic (nearly) on the excitation grid has no such part
// and is left in; `on_grid` marks it.
struct Synchronous {
  Eigen::MatrixXd s, o;  // n x 2 per fitted harmonic: cos, sin and their non-periodic parts
  Eigen::LLT<Eigen::MatrixXd> gram;
  std::vector<double> lost;  // per bin k0 + b

  Synchronous(int64_t period, long m, double f1, int64_t k0, int64_t nb, std::vector<bool>& on_grid) {
    const int64_t n = m * period;
    lost.assign(static_cast<size_t>(nb), 0.0);
    std::vector<Eigen::Index> cols;
    Eigen::MatrixXd all(n, 2 * kSynchronousHarmonics), orth(n, 2 * kSynchronousHarmonics);
    for (int h = 1; h <= kSynchronousHarmonics && m >= 2; ++h) {
      const double f = h * f1;
      if (!(f > 0.0) || f >= 0.5) break;
      const Eigen::Index j = 2 * (h - 1);
      for (int64_t t = 0; t < n; ++t) {
        const double phase = 2.0 * std::numbers::pi * f * static_cast<double>(t);
        all(t, j) = std::cos(phase);
        all(t, j + 1) = std::sin(phase);
      }
      orth.middleCols(j, 2) = all.middleCols(j, 2);
      for (int64_t tau = 0; tau < period; ++tau) {
        Eigen::RowVector2d mean = Eigen::RowVector2d::Zero();
        for (long p = 0; p < m; ++p) mean += all.block(p * period + tau, j, 1, 2);
        mean /= static_cast<double>(m);
        for (long p = 0; p < m; ++p) orth.block(p * period + tau, j, 1, 2) -= mean;
      }
      // Less than this share of the sinusoids' energy outside the periodic
      // signals: at the line next to h f1 they cannot be told from the
      // excitation's response (that line is dropped). Near the grid but
      // not on it (1x at 50.01 Hz on 1 Hz lines: a 3000 rpm pump) the
      // sinusoid still leaks into the lines around it, above the noise
      // when the unbalance response is large; fitting it through its small
      // non-periodic part removes that. The fit's error grows as
      // share^(-1/2) and its leakage into the neighbours falls as
      // share^(1/2), so what it leaves there stays below the noise; only an exactly periodic harmonic (share ~ 0), which sits on
      // its line alone, is left in.
      const double share = orth.middleCols(j, 2).squaredNorm() / static_cast<double>(n);
      if (share < kSynchronousMinShare) on_grid[static_cast<size_t>(h - 1)] = true;
      if (share < kSynchronousFitShare) continue;
      cols.push_back(j);
      cols.push_back(j + 1);
    }
    if (cols.empty()) return;
    s = all(Eigen::all, cols);
    o = orth(Eigen::all, cols);
    gram.compute(o.transpose() * o);
    // Leverage per bin: the orthonormal q = O L^-T, per period, projected on
    // the bin's cos/sin pair (|DFT|^2 2 / N real dimensions).
    const Eigen::MatrixXd q = gram.matrixU().solve<Eigen::OnTheRight>(o);
    Eigen::FFT<double> fft;
    std::vector<double> buf(static_cast<size_t>(period));
    std::vector<std::complex<double>> spec;
    for (Eigen::Index j = 0; j < q.cols(); ++j) {
      for (long p = 0; p < m; ++p) {
        for (int64_t t = 0; t < period; ++t) buf[static_cast<size_t>(t)] = q(p * period + t, j);
        fft.fwd(spec, buf);
        for (int64_t b = 0; b < nb; ++b)
          lost[static_cast<size_t>(b)] += std::norm(spec[static_cast<size_t>(k0 + b)]) / static_cast<double>(period);
      }
    }
  }
  // x minus its synchronous response.
  void remove(std::vector<double>& x) const {
    if (s.cols() == 0) return;
    Eigen::Map<Eigen::VectorXd> xv(x.data(), static_cast<Eigen::Index>(x.size()));
    const Eigen::VectorXd c = gram.solve(o.transpose() * xv);
    xv.noalias() -= s * c;
  }
};

// DFT of each usable period of every channel, scaled to amplitudes (2/N),
// kept at bins [k0, k0 + nb), then mean and scatter over the periods. The
// measured channels are first rid of the rotor's synchronous response
// (f1_per_sample > 0: the run's speed).
SegmentSpectra segment_spectra(const RunRecording& run, const ChannelPlan& plan, const ExcitationSegment& seg,
                               int64_t period, int64_t k0, int64_t nb, double f1_per_sample,
                               std::vector<bool>& on_grid) {
  const std::vector<int> zc = plan.measured_channels();
  const std::vector<int>& rc = plan.reference_channels;
  const auto nz = static_cast<Eigen::Index>(zc.size()), nr = static_cast<Eigen::Index>(rc.size());
  SegmentSpectra s;
  s.periods = static_cast<long>(seg.periods - seg.settle_periods);
  const auto m = s.periods;
  // spectra[p](c, b): period p, channel c (z then r), bin b.
  std::vector<Eigen::MatrixXcd> spectra(static_cast<size_t>(m), Eigen::MatrixXcd(nz + nr, nb));
  Eigen::FFT<double> fft;
  std::vector<double> window(static_cast<size_t>(m * period)), buf(static_cast<size_t>(period));
  std::vector<std::complex<double>> spec;
  const double scale = 2.0 / static_cast<double>(period);
  const int64_t begin = seg.start + seg.settle_periods * period;
  const Synchronous sync(period, m, f1_per_sample, k0, nb, on_grid);
  s.lost_dof = sync.lost;
  for (Eigen::Index c = 0; c < nz + nr; ++c) {
    const int ch = c < nz ? zc[static_cast<size_t>(c)] : rc[static_cast<size_t>(c - nz)];
    for (int64_t t = 0; t < m * period; ++t) window[static_cast<size_t>(t)] = run.at(begin + t, ch);
    if (c < nz) sync.remove(window);
    for (long p = 0; p < m; ++p) {
      std::copy_n(window.begin() + p * period, period, buf.begin());
      fft.fwd(spec, buf);
      for (int64_t b = 0; b < nb; ++b)
        spectra[static_cast<size_t>(p)](c, b) = scale * spec[static_cast<size_t>(k0 + b)];
    }
  }
  s.z_mean.resize(static_cast<size_t>(nb));
  s.r_mean.resize(static_cast<size_t>(nb));
  s.z_ss.resize(static_cast<size_t>(nb));
  for (int64_t b = 0; b < nb; ++b) {
    Eigen::VectorXcd mean = Eigen::VectorXcd::Zero(nz + nr);
    for (long p = 0; p < m; ++p) mean += spectra[static_cast<size_t>(p)].col(b);
    mean /= static_cast<double>(m);
    s.z_mean[static_cast<size_t>(b)] = mean.head(nz);
    s.r_mean[static_cast<size_t>(b)] = mean.tail(nr);
    s.reference_power += mean.tail(nr).squaredNorm();
    Eigen::MatrixXcd ss = Eigen::MatrixXcd::Zero(nz, nz);
    for (long p = 0; p < m; ++p) {
      const Eigen::VectorXcd d = spectra[static_cast<size_t>(p)].col(b).head(nz) - mean.head(nz);
      ss += d * d.adjoint();
    }
    s.z_ss[static_cast<size_t>(b)] = std::move(ss);
  }
  return s;
}

}  // namespace

FrfEstimate estimate_multisine(const RunRecording& run, const ChannelPlan& plan,
                               const FrfEstimationOptions& options) {
  const Excitation& ex = *run.excitation;
  const int64_t period = ex.period_samples;
  if (period < 4) throw InputError("excitation.period_samples: must be >= 4");
  const double fs = run.sample_rate_hz, df = fs / static_cast<double>(period);
  const int64_t k_lo = std::max<int64_t>(1, static_cast<int64_t>(std::ceil(ex.f_min_hz / df - 1e-9)));
  const int64_t k_hi =
      std::min<int64_t>(static_cast<int64_t>(std::floor(ex.f_max_hz / df + 1e-9)), (period - 1) / 2);
  if (k_hi < k_lo) {
    throw InputError("excitation: no DFT line between f_min_hz and f_max_hz at " +
                     frf_estimation::format_number(df) + " Hz spacing");
  }
  const int64_t nb = k_hi - k_lo + 1;

  FrfEstimate est;
  est.method = "multisine";
  frf_estimation::Windows windows;
  for (size_t i = 0; i < ex.segments.size(); ++i) {
    const auto& s = ex.segments[i];
    windows.push_back({s.start + s.settle_periods * period, s.start + s.periods * period});
  }
  frf_estimation::check_references(run, plan, windows);
  frf_estimation::check_clipping(run, plan, windows);

  // The synchronous response (unbalance at 1x, ...) is deterministic but
  // not periodic with the excitation unless the speed sits on its grid:
  // left in, it would leak into every line near h x speed and into the
  // period-to-period variance.
  const double f1_per_sample = run.speed_rpm > 0.0 ? run.speed_rpm / 60.0 / fs : 0.0;
  std::vector<bool> on_grid(kSynchronousHarmonics, false);
  std::vector<SegmentSpectra> segs;
  for (size_t i = 0; i < ex.segments.size(); ++i) {
    const auto& s = ex.segments[i];
    if (s.periods - s.settle_periods < 1) {
      est.warnings.push_back("segment " + std::to_string(i) +
                             ": no period after the settle periods; skipped");
      continue;
    }
    segs.push_back(segment_spectra(run, plan, s, period, k_lo, nb, f1_per_sample, on_grid));
    segs.back().index = i;
  }
  // A harmonic on the excitation grid is periodic with it: its synchronous
  // response (unbalance at 1x: large) lands on the nearest line as if it
  // were the plant's response to the excitation. That line is dropped, not
  // kept with a wrong H and a sigma that does not know it.
  std::vector<std::pair<int64_t, std::string>> synchronous_lines;  // bin, why
  for (int h = 1; h <= kSynchronousHarmonics; ++h) {
    const double f_hz = h * f1_per_sample * fs;
    if (on_grid[static_cast<size_t>(h - 1)] && f_hz >= k_lo * df && f_hz <= k_hi * df)
      synchronous_lines.push_back({std::llround(f_hz / df) - k_lo,
                                   std::to_string(h) + "x the speed (" + frf_estimation::format_number(f_hz) +
                                       " Hz) is periodic with the excitation: its synchronous response cannot be told "
                                       "from H there"});
  }
  double top = 0.0;
  for (const auto& s : segs) top = std::max(top, s.reference_power);
  std::erase_if(segs, [&](const SegmentSpectra& s) {
    if (s.reference_power > kDeadSegmentFraction * top) return false;
    est.warnings.push_back("segment " + std::to_string(s.index) + ": the references are zero; skipped");
    return true;
  });
  const int n_in = plan.n_in(), n_out = plan.n_out();
  if (static_cast<int>(segs.size()) < n_in) {
    throw InputError("excitation.segments: " + std::to_string(segs.size()) + " usable segment(s) for " +
                     std::to_string(n_in) + " inputs; X = H F needs at least " + std::to_string(n_in) +
                     " segments with linearly independent patterns");
  }
  long dof = 0;  // of the pooled covariance, before the synchronous fit
  for (const auto& s : segs) dof += s.periods - 1;
  const bool with_sigma = dof > 0;
  // Per bin, less what the synchronous fit took there.
  std::vector<double> bin_dof(static_cast<size_t>(nb), static_cast<double>(dof));
  for (const auto& s : segs)
    for (int64_t b = 0; b < nb; ++b) bin_dof[static_cast<size_t>(b)] -= s.lost_dof[static_cast<size_t>(b)];
  if (!with_sigma) {
    est.warnings.push_back(
        "every segment has a single period after its settle periods: no period-to-period variance, sigma "
        "and coherence left out");
  } else if (dof < kFewDegreesOfFreedom) {
    est.warnings.push_back("sigma rests on " + std::to_string(dof) +
                           " degree(s) of freedom only (periods after the settle periods, minus one per "
                           "segment): it is uncertain");
  }
  double mean_periods = 0.0;
  for (const auto& s : segs) mean_periods += static_cast<double>(s.periods);
  mean_periods /= static_cast<double>(segs.size());
  est.averages = std::lround(mean_periods);

  // Excited lines: reference power over all segments and references.
  std::vector<double> power(static_cast<size_t>(nb), 0.0);
  for (const auto& s : segs) {
    for (int64_t b = 0; b < nb; ++b)
      power[static_cast<size_t>(b)] += s.r_mean[static_cast<size_t>(b)].squaredNorm();
  }
  const double max_power = *std::max_element(power.begin(), power.end());

  frf_estimation::FrfAssembler out(plan, with_sigma, with_sigma);
  std::vector<Experiment> exps(segs.size());
  std::vector<double> line_dof;
  Eigen::MatrixXd coh(n_out, n_in);
  for (int64_t b = 0; b < nb; ++b) {
    if (!(power[static_cast<size_t>(b)] > kExcitedPowerFraction * max_power)) continue;
    const double f_hz = static_cast<double>(k_lo + b) * df;
    if (const auto sync = std::find_if(synchronous_lines.begin(), synchronous_lines.end(),
                                       [&](const auto& l) { return l.first == b; });
        sync != synchronous_lines.end()) {
      out.drop(f_hz, sync->second);
      continue;
    }
    // Pooled per-period covariance; the mean of M_k periods has 1 / M_k of it.
    Eigen::MatrixXcd pooled;
    if (with_sigma) {
      pooled = segs.front().z_ss[static_cast<size_t>(b)];
      for (size_t k = 1; k < segs.size(); ++k) pooled += segs[k].z_ss[static_cast<size_t>(b)];
      pooled /= bin_dof[static_cast<size_t>(b)];
      line_dof.push_back(bin_dof[static_cast<size_t>(b)]);
    }
    for (size_t k = 0; k < segs.size(); ++k) {
      exps[k].z = segs[k].z_mean[static_cast<size_t>(b)];
      exps[k].r = segs[k].r_mean[static_cast<size_t>(b)];
      exps[k].cov =
          with_sigma ? Eigen::MatrixXcd(pooled / static_cast<double>(segs[k].periods)) : Eigen::MatrixXcd();
      exps[k].averages = static_cast<double>(segs[k].periods);
    }
    const frf_estimation::LineSolution sol = frf_estimation::solve_line(exps, n_out, n_in);
    if (sol.h.size() == 0 || sol.rcond < options.min_rcond) {
      out.drop(f_hz, "the segments' patterns are not linearly independent there (singular S_fr)");
      continue;
    }
    out.note_rcond(f_hz, sol.rcond, options.warn_rcond);
    if (with_sigma) {
      for (int o = 0; o < n_out; ++o) {
        for (int i = 0; i < n_in; ++i) {
          coh(o, i) = frf_estimation::coherence_from_sigma(sol.h(o, i), sol.sigma(o, i), mean_periods);
        }
      }
    }
    out.add(f_hz, sol.h, sol.sigma, coh);
  }
  est.frf = out.finish(est.warnings, est.lines_dropped, "multisine");
  // One figure for the file: the median over the lines (real: twice the
  // complex ones), rounded down; only the few lines next to h x speed have
  // fewer.
  if (with_sigma && !line_dof.empty()) {
    std::nth_element(line_dof.begin(), line_dof.begin() + static_cast<long>(line_dof.size() / 2), line_dof.end());
    est.sigma_dof = static_cast<long>(std::floor(2.0 * line_dof[line_dof.size() / 2] + 1e-9));
  }
  return est;
}

}  // namespace ambdiag
