// Multisine runs: per segment, the settle periods dropped, the DFT of every
// remaining period averaged at the excited bins; one experiment per segment;
// H per line from (1) of frf_estimation.h, sigma by (2) from the
// period-to-period covariance of [x; f]. The noise does not depend on the
// phase pattern (measurement noise, or process noise through a linear loop),
// so the covariance is pooled over the segments: sum (M_k - 1) degrees of
// freedom instead of M_k - 1 each, which keeps 1 / sigma^2 nearly unbiased.
#include <algorithm>
#include <cmath>
#include <complex>
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

struct SegmentSpectra {
  size_t index = 0;
  long periods = 0;                      // usable
  std::vector<Eigen::VectorXcd> z_mean;  // per bin: outputs then inputs
  std::vector<Eigen::VectorXcd> r_mean;  // per bin: references
  std::vector<Eigen::MatrixXcd> z_ss;    // per bin: sum over periods of (z_p - mean)(z_p - mean)^H
  double reference_power = 0.0;
};

// DFT of each usable period of every channel, scaled to amplitudes (2/N),
// kept at bins [k0, k0 + nb), then mean and scatter over the periods.
SegmentSpectra segment_spectra(const RunRecording& run, const ChannelPlan& plan, const ExcitationSegment& seg,
                               int64_t period, int64_t k0, int64_t nb) {
  const std::vector<int> zc = plan.measured_channels();
  const std::vector<int>& rc = plan.reference_channels;
  const auto nz = static_cast<Eigen::Index>(zc.size()), nr = static_cast<Eigen::Index>(rc.size());
  SegmentSpectra s;
  s.periods = static_cast<long>(seg.periods - seg.settle_periods);
  const auto m = s.periods;
  // spectra[p](c, b): period p, channel c (z then r), bin b.
  std::vector<Eigen::MatrixXcd> spectra(static_cast<size_t>(m), Eigen::MatrixXcd(nz + nr, nb));
  Eigen::FFT<double> fft;
  std::vector<double> buf(static_cast<size_t>(period));
  std::vector<std::complex<double>> spec;
  const double scale = 2.0 / static_cast<double>(period);
  for (long p = 0; p < m; ++p) {
    const int64_t begin = seg.start + (seg.settle_periods + p) * period;
    for (Eigen::Index c = 0; c < nz + nr; ++c) {
      const int ch = c < nz ? zc[static_cast<size_t>(c)] : rc[static_cast<size_t>(c - nz)];
      for (int64_t t = 0; t < period; ++t) buf[static_cast<size_t>(t)] = run.at(begin + t, ch);
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

  std::vector<SegmentSpectra> segs;
  for (size_t i = 0; i < ex.segments.size(); ++i) {
    const auto& s = ex.segments[i];
    if (s.periods - s.settle_periods < 1) {
      est.warnings.push_back("segment " + std::to_string(i) +
                             ": no period after the settle periods; skipped");
      continue;
    }
    segs.push_back(segment_spectra(run, plan, s, period, k_lo, nb));
    segs.back().index = i;
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
  long dof = 0;  // of the pooled covariance
  for (const auto& s : segs) dof += s.periods - 1;
  const bool with_sigma = dof > 0;
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
  Eigen::MatrixXd coh(n_out, n_in);
  for (int64_t b = 0; b < nb; ++b) {
    if (!(power[static_cast<size_t>(b)] > kExcitedPowerFraction * max_power)) continue;
    const double f_hz = static_cast<double>(k_lo + b) * df;
    // Pooled per-period covariance; the mean of M_k periods has 1 / M_k of it.
    Eigen::MatrixXcd pooled;
    if (with_sigma) {
      pooled = segs.front().z_ss[static_cast<size_t>(b)];
      for (size_t k = 1; k < segs.size(); ++k) pooled += segs[k].z_ss[static_cast<size_t>(b)];
      pooled /= static_cast<double>(dof);
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
  return est;
}

}  // namespace ambdiag
