// Chirp runs: deconvolution of the whole segments and time gating of the
// impulse responses (the swept-sine technique of acoustics: A. Farina, AES
// preprint 5093, 2000; gating as in ISO 18233).
//
// A sweep excites each line once, for a moment, while the noise lasts the
// whole record. The ratio of whole-record spectra (1) of frf_estimation.h
// (H = S_xr S_fr^-1 with the segments as experiments, one per input) is
// unbiased but collects the noise of the whole record at every line. Its
// inverse DFT, the impulse response h(t), holds the system's response in
// the first T_g seconds and only noise (and, at negative times, the
// harmonic distortion of an up-sweep) elsewhere. Keeping h over
// [-T_g / 16, T_g] (half-Hann tapers at both ends) removes the noise outside
// and leaves the response: H_g = DFT(g h). T_g is where the smoothed h^2 of
// all entries has decayed into the noise floor of the record's middle, times
// 1.5; windows of the same shape placed in that noise-only middle give the
// noise of H_g per line (averaged over the windows and over the N / T_g
// lines of 3 resolution cells each side): sigma. Lines are written every
// N / T_g DFT lines (one per resolution cell, about independent). Welch windows instead cut each line's
// ringing at a place that depends on when the sweep crossed it, which biases
// lightly damped resonances.
#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <string>
#include <vector>

#include <unsupported/Eigen/FFT>

#include "ambdiag/core/error.h"
#include "frf_estimation_internal.h"

namespace ambdiag {

using frf_estimation::ChannelPlan;
using frf_estimation::median_excited_power;
using frf_estimation::Experiment;

namespace {

constexpr double kExcitedPowerFraction = 1e-6;
constexpr double kWeakLineFraction = 1e-2;   // of the median excited line's reference power
constexpr double kEdgeTaperFraction = 0.01;  // band lines tapered (and not written) at each band edge
constexpr int64_t kNoiseCells = 3;

// Gate over [-pre, len) of a circular signal of length n: 1 inside,
// half-Hann tapers over the first `pre` samples and the last quarter.
std::vector<double> gate(int64_t n, int64_t len, int64_t pre, int64_t shift) {
  std::vector<double> g(static_cast<size_t>(n), 0.0);
  const int64_t fall = std::max<int64_t>(1, len / 4);
  for (int64_t t = -pre; t < len; ++t) {
    double w = 1.0;
    if (t < 0)
      w = std::pow(std::sin(0.5 * std::numbers::pi * static_cast<double>(t + pre) / static_cast<double>(pre)),
                   2);
    if (t >= len - fall)
      w = std::pow(std::cos(0.5 * std::numbers::pi * static_cast<double>(t - (len - fall)) /
                            static_cast<double>(fall)),
                   2);
    g[static_cast<size_t>(((t + shift) % n + n) % n)] = w;
  }
  return g;
}

}  // namespace

FrfEstimate estimate_gated(const RunRecording& run, const ChannelPlan& plan,
                           const FrfEstimationOptions& options) {
  if (auto welch = welch_if_segments_differ(run, plan, options, "gating")) return *welch;
  const Excitation& ex = *run.excitation;
  const int64_t n = ex.segments.front().length;
  FrfEstimate est;
  est.method = "gated";
  const int n_out = plan.n_out(), n_in = plan.n_in(), n_seg = static_cast<int>(ex.segments.size());
  if (n < 256)
    throw InputError("excitation.segments: " + std::to_string(n) + " samples are too few for an FRF");
  if (n_seg < n_in) {
    throw InputError("excitation.segments: " + std::to_string(n_seg) + " sweep(s) for " +
                     std::to_string(n_in) + " inputs; X = H F needs at least one sweep per input");
  }
  frf_estimation::Windows segments;
  for (const auto& s : ex.segments) segments.push_back({s.start, s.start + s.length});
  frf_estimation::check_references(run, plan, segments);
  frf_estimation::check_clipping(run, plan, segments);

  const double fs = run.sample_rate_hz, df = fs / static_cast<double>(n);
  const double f_max = ex.f_max_hz > 0.0 ? ex.f_max_hz : fs / 2.0;
  const int64_t last = (n - 1) / 2;
  const int64_t k_lo = std::max<int64_t>(1, static_cast<int64_t>(std::ceil(ex.f_min_hz / df - 1e-9)));
  const int64_t k_hi = std::min<int64_t>(static_cast<int64_t>(std::floor(f_max / df + 1e-9)), last);
  if (k_hi - k_lo < 64) throw InputError("excitation: too few lines between f_min_hz and f_max_hz");

  // Whole-segment spectra and the per-line solve (1).
  const std::vector<int> zc = plan.measured_channels();
  const auto nz = static_cast<Eigen::Index>(zc.size());
  Eigen::FFT<double> fft;
  std::vector<double> buf(static_cast<size_t>(n));
  std::vector<std::complex<double>> spec;
  std::vector<Experiment> exps(static_cast<size_t>(n_seg));
  std::vector<Eigen::MatrixXcd> zs(static_cast<size_t>(n_seg)), rs(static_cast<size_t>(n_seg));
  for (int s = 0; s < n_seg; ++s) {
    const int64_t start = ex.segments[static_cast<size_t>(s)].start;
    zs[static_cast<size_t>(s)].resize(nz, k_hi - k_lo + 1);
    rs[static_cast<size_t>(s)].resize(n_in, k_hi - k_lo + 1);
    for (Eigen::Index c = 0; c < nz + n_in; ++c) {
      const int ch =
          c < nz ? zc[static_cast<size_t>(c)] : plan.reference_channels[static_cast<size_t>(c - nz)];
      for (int64_t t = 0; t < n; ++t) buf[static_cast<size_t>(t)] = run.at(start + t, ch);
      fft.fwd(spec, buf);
      for (int64_t k = k_lo; k <= k_hi; ++k) {
        (c < nz ? zs[static_cast<size_t>(s)](c, k - k_lo) : rs[static_cast<size_t>(s)](c - nz, k - k_lo)) =
            spec[static_cast<size_t>(k)];
      }
    }
  }
  const auto nb = static_cast<size_t>(k_hi - k_lo + 1);
  std::vector<double> power(nb, 0.0);
  for (size_t b = 0; b < nb; ++b) {
    for (int s = 0; s < n_seg; ++s)
      power[b] += rs[static_cast<size_t>(s)].col(static_cast<Eigen::Index>(b)).squaredNorm();
  }
  const double max_power = *std::max_element(power.begin(), power.end());
  const double median_power = median_excited_power(power, kExcitedPowerFraction);

  // H of every line of the band; lines that cannot be solved are zero in the
  // impulse response and not written.
  std::vector<Eigen::MatrixXcd> h_full(nb, Eigen::MatrixXcd::Zero(n_out, n_in));
  std::vector<bool> usable(nb, false);
  frf_estimation::FrfAssembler out(plan, true, true);
  long unexcited = 0;
  for (size_t b = 0; b < nb; ++b) {
    const double f_hz = static_cast<double>(k_lo + static_cast<int64_t>(b)) * df;
    if (!(power[b] > kExcitedPowerFraction * max_power)) {
      ++unexcited;
      continue;
    }
    if (power[b] < kWeakLineFraction * median_power) {
      out.drop(f_hz, "the references have less than 1 % of their median power there");
      continue;
    }
    for (int s = 0; s < n_seg; ++s) {
      exps[static_cast<size_t>(s)].z = zs[static_cast<size_t>(s)].col(static_cast<Eigen::Index>(b));
      exps[static_cast<size_t>(s)].r = rs[static_cast<size_t>(s)].col(static_cast<Eigen::Index>(b));
    }
    const frf_estimation::LineSolution sol = frf_estimation::solve_line(exps, n_out, n_in);
    if (sol.h.size() == 0 || sol.rcond < options.min_rcond) {
      out.drop(f_hz, "the sweeps' input spectra are nearly dependent (singular S_fr)");
      continue;
    }
    out.note_rcond(f_hz, sol.rcond, options.warn_rcond);
    h_full[b] = sol.h;
    usable[b] = true;
  }

  // Impulse responses, band edges tapered.
  const auto taper_lines =
      static_cast<size_t>(std::max<double>(8.0, kEdgeTaperFraction * static_cast<double>(nb)));
  const int n_entries = n_out * n_in;
  std::vector<std::vector<double>> ir(static_cast<size_t>(n_entries));
  std::vector<std::complex<double>> full(static_cast<size_t>(n));
  for (int e = 0; e < n_entries; ++e) {
    std::fill(full.begin(), full.end(), 0.0);
    for (size_t b = 0; b < nb; ++b) {
      const size_t edge = std::min(b, nb - 1 - b);
      const double w = edge >= taper_lines
                           ? 1.0
                           : std::pow(std::sin(0.5 * std::numbers::pi * static_cast<double>(edge + 1) /
                                               static_cast<double>(taper_lines + 1)),
                                      2);
      const std::complex<double> v = w * h_full[b](e / n_in, e % n_in);
      const auto k = static_cast<size_t>(k_lo) + b;
      full[k] = v;
      full[static_cast<size_t>(n) - k] = std::conj(v);
    }
    fft.inv(ir[static_cast<size_t>(e)], full);
  }

  // Gate length: where the smoothed h^2, each entry scaled by its noise floor
  // in the middle of the record, has decayed to twice the floor.
  const int64_t smooth = std::max<int64_t>(8, n / 512);
  std::vector<double> env(static_cast<size_t>(n / 2), 0.0);
  for (const auto& h : ir) {
    std::vector<double> sq(static_cast<size_t>(n / 2));
    for (int64_t t = 0; t < n / 2; ++t)
      sq[static_cast<size_t>(t)] = h[static_cast<size_t>(t)] * h[static_cast<size_t>(t)];
    std::vector<double> mid(sq.begin() + static_cast<long>(0.35 * static_cast<double>(n)), sq.end());
    std::nth_element(mid.begin(), mid.begin() + static_cast<long>(mid.size() / 2), mid.end());
    const double floor = mid[mid.size() / 2] / std::log(2.0);  // median of an exponential -> mean
    if (!(floor > 0.0)) continue;
    for (int64_t t = 0; t < n / 2; ++t) env[static_cast<size_t>(t)] += sq[static_cast<size_t>(t)] / floor;
  }
  double acc = 0.0;
  int64_t decayed = smooth;
  const double floor_all = static_cast<double>(n_entries);
  std::vector<double> avg(env.size(), 0.0);
  for (size_t t = 0; t < env.size(); ++t) {
    acc += env[t] - (t >= static_cast<size_t>(smooth) ? env[t - static_cast<size_t>(smooth)] : 0.0);
    avg[t] = acc / static_cast<double>(smooth);
  }
  for (int64_t t = static_cast<int64_t>(0.35 * static_cast<double>(n)); t >= smooth; --t) {
    if (avg[static_cast<size_t>(t)] > 2.0 * floor_all) {
      decayed = t;
      break;
    }
  }
  const int64_t len =
      std::clamp<int64_t>(static_cast<int64_t>(1.5 * static_cast<double>(decayed)), n / 64, n / 4);
  const int64_t pre = std::max<int64_t>(4, len / 16);
  // Noise windows: same shape, half overlapping, in [1.25 len, n - len / 4].
  std::vector<int64_t> shifts;
  for (int64_t s = len + len / 4 + pre; s + len + len / 4 <= n; s += (len + pre) / 2) shifts.push_back(s);
  if (shifts.empty())
    throw InputError("excitation.segments: the impulse response does not decay within the record");
  const std::vector<double> g = gate(n, len, pre, 0);
  const int64_t cell = std::max<int64_t>(1, n / len);  // lines per resolution cell
  const int64_t step = cell;

  std::vector<Eigen::MatrixXcd> h_gated(nb, Eigen::MatrixXcd::Zero(n_out, n_in));
  std::vector<Eigen::MatrixXd> noise(nb, Eigen::MatrixXd::Zero(n_out, n_in));
  std::vector<double> gated(static_cast<size_t>(n));
  for (int e = 0; e < n_entries; ++e) {
    const auto& h = ir[static_cast<size_t>(e)];
    for (int64_t t = 0; t < n; ++t)
      gated[static_cast<size_t>(t)] = g[static_cast<size_t>(t)] * h[static_cast<size_t>(t)];
    fft.fwd(spec, gated);
    for (size_t b = 0; b < nb; ++b) h_gated[b](e / n_in, e % n_in) = spec[static_cast<size_t>(k_lo) + b];
    std::vector<double> p(nb, 0.0);
    for (int64_t s : shifts) {
      const std::vector<double> gs = gate(n, len, pre, s);
      for (int64_t t = 0; t < n; ++t)
        gated[static_cast<size_t>(t)] = gs[static_cast<size_t>(t)] * h[static_cast<size_t>(t)];
      fft.fwd(spec, gated);
      for (size_t b = 0; b < nb; ++b) p[b] += std::norm(spec[static_cast<size_t>(k_lo) + b]);
    }
    // Average over the windows and over kNoiseCells resolution cells each
    // side of the line (the noise spectrum is smooth on that scale).
    for (size_t b = 0; b < nb; ++b) {
      const auto span = static_cast<size_t>(kNoiseCells * cell);
      const size_t lo = b >= span ? b - span : 0;
      const size_t hi = std::min(nb - 1, b + span);
      double sum = 0.0;
      for (size_t j = lo; j <= hi; ++j) sum += p[j];
      noise[b](e / n_in, e % n_in) =
          sum / (static_cast<double>(hi - lo + 1) * static_cast<double>(shifts.size()));
    }
  }

  Eigen::MatrixXd sigma(n_out, n_in), coh(n_out, n_in);
  for (size_t b = 0; b < nb; b += static_cast<size_t>(step)) {
    if (!usable[b] || std::min(b, nb - 1 - b) < taper_lines) continue;
    sigma = noise[b].cwiseSqrt();
    for (int o = 0; o < n_out; ++o) {
      for (int i = 0; i < n_in; ++i) {
        coh(o, i) = frf_estimation::coherence_from_sigma(h_gated[b](o, i), sigma(o, i), 1.0);
      }
    }
    out.add(static_cast<double>(k_lo + static_cast<int64_t>(b)) * df, h_gated[b], sigma, coh);
  }
  est.frf = out.finish(est.warnings, est.lines_dropped, "gated");
  est.lines_dropped += unexcited;
  est.averages = n_seg;
  est.frf.set_meta("gate_s", frf_estimation::format_number(static_cast<double>(len) / fs));
  return est;
}

}  // namespace ambdiag
