// Step-sine runs: per segment a single-bin DFT (lock-in) of the last
// meas_samples, which hold whole periods, so the line has no leakage; the
// segments at one frequency (one per input) are the experiments of (1) in
// frf_estimation.h. The noise covariance of a segment's DFT comes from the
// unexcited bins next to the line in the same window (Pintelon & Schoukens
// 2012: noise from non-excited lines), which follows colored closed-loop
// noise and catches what is left of the transient; it is pooled over the
// segments of one step (the noise does not depend on which input is
// driven), scaled by each window's length.
#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <string>
#include <vector>

#include "ambdiag/core/error.h"
#include "frf_estimation_internal.h"

namespace ambdiag {

using frf_estimation::ChannelPlan;
using frf_estimation::Experiment;

namespace {

// Neighbouring bins on each side used for the noise covariance.
constexpr int64_t kNoiseBinsPerSide = 4;
// Frequencies closer than this (relative) are one step.
constexpr double kSameFrequency = 1e-9;

struct StepExperiment {
  int input = -1;      // index into plan.inputs
  int noise_bins = 0;  // bins averaged into ex.cov
  double samples = 0;  // window length
  Experiment ex;
};

// DFTs of the channels at bin `bin` of the window, scaled to amplitudes.
Eigen::VectorXcd window_dft(const RunRecording& run, const std::vector<int>& channels, int64_t begin,
                            int64_t n, int64_t bin, const std::vector<std::complex<double>>& twiddle) {
  Eigen::VectorXcd z = Eigen::VectorXcd::Zero(static_cast<Eigen::Index>(channels.size()));
  int64_t idx = 0;
  for (int64_t t = 0; t < n; ++t) {
    const std::complex<double> w = twiddle[static_cast<size_t>(idx)];
    for (size_t c = 0; c < channels.size(); ++c)
      z(static_cast<Eigen::Index>(c)) += static_cast<double>(run.at(begin + t, channels[c])) * w;
    idx += bin;
    if (idx >= n) idx -= n;
  }
  return z * (2.0 / static_cast<double>(n));
}

StepExperiment lock_in(const RunRecording& run, const ChannelPlan& plan, const ExcitationSegment& seg) {
  const int64_t n = seg.meas_samples, begin = seg.start + seg.length - seg.meas_samples, m = seg.periods;
  std::vector<std::complex<double>> twiddle(static_cast<size_t>(n));
  for (int64_t t = 0; t < n; ++t) {
    twiddle[static_cast<size_t>(t)] =
        std::polar(1.0, -2.0 * std::numbers::pi * static_cast<double>(t) / static_cast<double>(n));
  }
  const std::vector<int> zc = plan.measured_channels();
  StepExperiment s;
  s.ex.z = window_dft(run, zc, begin, n, m, twiddle);
  s.ex.r = window_dft(run, plan.reference_channels, begin, n, m, twiddle);
  s.ex.averages = static_cast<double>(m);
  // Noise: bins m-K..m+K except m, bin 0 (offset) and the Nyquist bin.
  Eigen::MatrixXcd cov =
      Eigen::MatrixXcd::Zero(static_cast<Eigen::Index>(zc.size()), static_cast<Eigen::Index>(zc.size()));
  int used = 0;
  for (int64_t b = m - kNoiseBinsPerSide; b <= m + kNoiseBinsPerSide; ++b) {
    if (b == m || b < 1 || 2 * b >= n) continue;
    const Eigen::VectorXcd d = window_dft(run, zc, begin, n, b, twiddle);
    cov += d * d.adjoint();
    ++used;
  }
  s.noise_bins = used;
  s.samples = static_cast<double>(n);
  s.ex.cov = used > 0 ? Eigen::MatrixXcd(cov / static_cast<double>(used)) : cov;
  for (int i = 0; i < plan.n_in(); ++i) {
    if (run.channels[static_cast<size_t>(plan.reference_channels[static_cast<size_t>(i)])].input ==
            seg.input ||
        plan.inputs[static_cast<size_t>(i)] == seg.input) {
      s.input = i;
    }
  }
  return s;
}

}  // namespace

FrfEstimate estimate_stepsine(const RunRecording& run, const ChannelPlan& plan,
                              const FrfEstimationOptions& options) {
  const Excitation& ex = *run.excitation;
  FrfEstimate est;
  est.method = "stepsine";
  frf_estimation::Windows windows;
  for (const auto& s : ex.segments)
    windows.push_back({s.start + s.length - s.meas_samples, s.start + s.length});
  frf_estimation::check_references(run, plan, windows);
  frf_estimation::check_clipping(run, plan, windows);

  // Segments sorted by frequency, then grouped into steps.
  std::vector<size_t> order(ex.segments.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return ex.segments[a].freq_hz < ex.segments[b].freq_hz; });

  const int n_in = plan.n_in(), n_out = plan.n_out();
  frf_estimation::FrfAssembler out(plan, true, true);
  std::vector<std::string> zero_refs;
  Eigen::MatrixXd coh(n_out, n_in);
  double periods_sum = 0.0;
  long periods_count = 0;
  int min_bins = -1;  // complex degrees of freedom of the pooled noise, fewest over the lines
  for (size_t g = 0; g < order.size();) {
    size_t end = g + 1;
    const double f_hz = ex.segments[order[g]].freq_hz;
    while (end < order.size() && ex.segments[order[end]].freq_hz - f_hz <= kSameFrequency * f_hz) ++end;
    std::vector<StepExperiment> steps;
    std::vector<bool> driven(static_cast<size_t>(n_in), false);
    double periods = 0.0;
    for (size_t k = g; k < end; ++k) {
      const ExcitationSegment& seg = ex.segments[order[k]];
      StepExperiment s = lock_in(run, plan, seg);
      if (s.input < 0) continue;  // the reader refuses an input without a reference
      const double amp = std::abs(s.ex.r(s.input));
      if (!(amp > 1e-3 * seg.amplitude)) {
        zero_refs.push_back("segment " + std::to_string(order[k]) + " (" + seg.input + " at " +
                            frf_estimation::format_number(seg.freq_hz) + " Hz)");
        continue;
      }
      driven[static_cast<size_t>(s.input)] = true;
      periods += s.ex.averages;
      steps.push_back(std::move(s));
    }
    g = end;
    std::string missing;
    for (int i = 0; i < n_in; ++i) {
      if (!driven[static_cast<size_t>(i)])
        missing += (missing.empty() ? "" : ", ") + plan.inputs[static_cast<size_t>(i)];
    }
    if (!missing.empty()) {
      out.drop(f_hz, "no usable segment drives " + missing + " at that frequency");
      continue;
    }
    // Pooled noise per sample; a window of N samples has 1 / N of it.
    Eigen::MatrixXcd pooled =
        Eigen::MatrixXcd::Zero(steps.front().ex.cov.rows(), steps.front().ex.cov.cols());
    int bins = 0;
    for (const auto& st : steps) {
      pooled += st.ex.cov * (st.samples * st.noise_bins);
      bins += st.noise_bins;
    }
    std::vector<Experiment> exps;
    for (auto& st : steps) {
      st.ex.cov = bins > 0 ? Eigen::MatrixXcd(pooled / (bins * st.samples)) : Eigen::MatrixXcd();
      exps.push_back(std::move(st.ex));
    }
    const frf_estimation::LineSolution sol = frf_estimation::solve_line(exps, n_out, n_in);
    if (sol.h.size() == 0 || sol.rcond < options.min_rcond) {
      out.drop(f_hz, "the measured forces of the steps are nearly dependent (singular S_fr)");
      continue;
    }
    if (sol.sigma.size() == 0) {
      out.drop(f_hz, "the measured windows are too short for a noise estimate (no unexcited bin)");
      continue;
    }
    out.note_rcond(f_hz, sol.rcond, options.warn_rcond);
    min_bins = min_bins < 0 ? bins : std::min(min_bins, bins);
    periods /= static_cast<double>(exps.size());
    periods_sum += periods;
    ++periods_count;
    for (int o = 0; o < n_out; ++o) {
      for (int i = 0; i < n_in; ++i) {
        coh(o, i) = frf_estimation::coherence_from_sigma(sol.h(o, i), sol.sigma(o, i), periods);
      }
    }
    out.add(f_hz, sol.h, sol.sigma, coh);
  }
  if (!zero_refs.empty()) {
    std::string w = std::to_string(zero_refs.size()) + " segment(s) skipped, their reference is zero: ";
    for (size_t k = 0; k < zero_refs.size() && k < 5; ++k) w += (k ? ", " : "") + zero_refs[k];
    if (zero_refs.size() > 5) w += ", ...";
    est.warnings.push_back(w);
  }
  est.frf = out.finish(est.warnings, est.lines_dropped, "stepsine");
  est.averages = periods_count > 0 ? std::lround(periods_sum / static_cast<double>(periods_count)) : 0;
  est.sigma_dof = min_bins > 0 ? 2 * min_bins : 0;  // the noise bins pooled over a line's steps, fewest
  return est;
}

}  // namespace ambdiag
