// Chirp and random runs: Welch averaging (Hann windows, 50 % overlap, the
// window mean removed, windows inside segments) of the cross spectra of the
// responses, inputs and instruments, then per line
//   automatic: H = S_xr S_fr^-1 with the references as instruments ((1) of
//              frf_estimation.h; H1 when the inputs are the references);
//   h1:        H = S_xf S_ff^-1 (biased when the input is measured with
//              noise or fed back);
//   hv:        per output the total least squares solution, the eigenvector
//              of [S_ff S_fx; S_xf S_xx] for the smallest eigenvalue
//              (Hv; equal to H1 when the inputs are noise free).
// H and sigma use every window: windows without excitation at a line weigh
// nothing in S_xr and S_fr but tell the noise level (stationary noise
// assumed): var(e) = sum |e_k|^2 / (K - n_in), and (2) with the correlation
// of adjacent windows. Coherence: coh = |H|^2 / (|H|^2 + n sigma^2) as for
// the periodic estimators, with n the windows that carry at least
// kCoherenceWindowFraction of the line's strongest window's instrument
// power. For stationary random excitation n = K and this is the ordinary
// coherence S_xr S_rr^-1 S_rx / S_xx; for a sweep, which crosses a line in
// one or two windows, the ordinary coherence would be diluted by the noise
// of all other windows (or trivially 1 over the crossing windows alone).
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

namespace {

constexpr double kExcitedPowerFraction = 1e-6;  // of the strongest line's instrument power
constexpr double kCoherenceWindowFraction = 1e-2;
// Lines whose instrument power is below this fraction of the median over the
// excited lines (a sweep's tapered ends) are dropped with a warning.
constexpr double kWeakLineFraction = 1e-2;

long default_nfft(int64_t longest_segment, int64_t total, ExcitationType type) {
  // Largest power of two with at least `min_windows` windows' worth of data,
  // within one segment. Random excitation: 8 (15 half-overlapping windows,
  // the usual compromise of noise against window truncation bias). A sweep
  // excites each line once, so averaging gains nothing, while a line's
  // response must ring out inside the window that holds its passage: 4
  // (7 windows), leaving 6 degrees of freedom for the noise estimate.
  const int64_t min_windows = type == ExcitationType::chirp ? 4 : 8;
  long n = 64;
  while (2 * n <= 65536 && 2 * n * min_windows <= total && 2 * n <= longest_segment) n *= 2;
  return n;
}

std::string method_name(NonperiodicMethod m, bool inputs_are_references) {
  if (m == NonperiodicMethod::hv) return "welch-hv";
  if (m == NonperiodicMethod::h1 || inputs_are_references) return "welch-h1";
  return "welch-ref";
}

}  // namespace

std::optional<FrfEstimate> welch_if_segments_differ(const RunRecording& run, const ChannelPlan& plan,
                                                    const FrfEstimationOptions& options, const std::string& method) {
  const auto& segments = run.excitation->segments;
  const int64_t n = segments.front().length;
  if (std::all_of(segments.begin(), segments.end(), [&](const auto& s) { return s.length == n; })) return std::nullopt;
  FrfEstimationOptions welch = options;
  welch.method = NonperiodicMethod::welch;
  FrfEstimate est = estimate_welch(run, plan, welch);
  est.warnings.insert(est.warnings.begin(), "segments of different lengths: Welch averaging instead of " + method);
  return est;
}

FrfEstimate estimate_welch(const RunRecording& run, const ChannelPlan& plan,
                           const FrfEstimationOptions& options) {
  const Excitation& ex = *run.excitation;
  FrfEstimate est;
  est.method = method_name(options.method, plan.inputs_are_references);
  const int n_in = plan.n_in(), n_out = plan.n_out();

  frf_estimation::Windows segments;
  int64_t longest = 0, total = 0;
  for (const auto& s : ex.segments) {
    segments.push_back({s.start, s.start + s.length});
    longest = std::max(longest, s.length);
    total += s.length;
  }
  const long nfft = options.nfft > 0 ? options.nfft : default_nfft(longest, total, ex.type);
  const long hop = nfft / 2;
  frf_estimation::Windows windows;  // (start, segment) of each window; consecutive ones overlap
  std::vector<bool> follows;        // window k overlaps window k-1
  long short_segments = 0;
  for (const auto& [b, e] : segments) {
    if (e - b < nfft) ++short_segments;
    for (int64_t t = b; t + nfft <= e; t += hop) {
      follows.push_back(t > b);
      windows.push_back({t, t + nfft});
    }
  }
  if (short_segments > 0) {
    est.warnings.push_back(std::to_string(short_segments) + " segment(s) shorter than the window (" +
                           std::to_string(nfft) + " samples) skipped");
  }
  const auto n_win = static_cast<long>(windows.size());
  if (n_win < 2) {
    throw InputError("excitation.segments: " + std::to_string(n_win) + " Welch window(s) of " +
                     std::to_string(nfft) +
                     " samples fit in the run; at least 2 are needed (a shorter nfft or a longer run)");
  }
  frf_estimation::check_references(run, plan, segments);
  frf_estimation::check_clipping(run, plan, segments);
  if (n_win <= n_in) {
    est.warnings.push_back("only " + std::to_string(n_win) + " windows for " + std::to_string(n_in) +
                           " inputs: no residual degrees of freedom, sigma left out");
  }

  const double fs = run.sample_rate_hz, df = fs / static_cast<double>(nfft);
  const double f_max = ex.f_max_hz > 0.0 ? ex.f_max_hz : fs / 2.0;
  // Bin 1 lies in the Hann main lobe of the offset and of slow drifts: from bin 2.
  const long k_lo = std::max<long>(2, static_cast<long>(std::ceil(ex.f_min_hz / df - 1e-9)));
  const long k_hi = std::min<long>(static_cast<long>(std::floor(f_max / df + 1e-9)), nfft / 2 - 1);
  if (k_hi < k_lo)
    throw InputError("excitation: no line between f_min_hz and f_max_hz at nfft " + std::to_string(nfft));
  const long nb = k_hi - k_lo + 1;

  // Channels: z = [outputs; inputs], then the instruments w.
  const bool use_refs = options.method != NonperiodicMethod::h1 && options.method != NonperiodicMethod::hv &&
                        !plan.inputs_are_references;
  std::vector<int> chans = plan.measured_channels();
  const auto nz = static_cast<Eigen::Index>(chans.size());
  if (use_refs) chans.insert(chans.end(), plan.reference_channels.begin(), plan.reference_channels.end());
  const auto na = static_cast<Eigen::Index>(chans.size());
  const Eigen::Index w0 = use_refs ? nz : n_out;  // first instrument row
  const Eigen::Index nw = n_in;

  std::vector<double> window(static_cast<size_t>(nfft));
  double w2 = 0.0, w_lag = 0.0;
  for (long t = 0; t < nfft; ++t) {
    window[static_cast<size_t>(t)] =
        0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(t) / static_cast<double>(nfft));
  }
  for (long t = 0; t < nfft; ++t) {
    w2 += window[static_cast<size_t>(t)] * window[static_cast<size_t>(t)];
    if (t + hop < nfft) w_lag += window[static_cast<size_t>(t)] * window[static_cast<size_t>(t + hop)];
  }
  const double rho = w_lag / w2;  // noise DFT correlation of adjacent windows, times (-1)^k at bin k

  Eigen::FFT<double> fft;
  std::vector<double> buf(static_cast<size_t>(nfft));
  std::vector<std::complex<double>> spec;
  // Windowed spectra of channel rows [c0, c1) of window k, into cur.
  Eigen::MatrixXcd cur(na, nb);
  const auto transform = [&](long k, Eigen::Index c0, Eigen::Index c1) {
    const int64_t begin = windows[static_cast<size_t>(k)].first;
    for (Eigen::Index c = c0; c < c1; ++c) {
      const int ch = chans[static_cast<size_t>(c)];
      double mean = 0.0;
      for (long t = 0; t < nfft; ++t) mean += run.at(begin + t, ch);
      mean /= static_cast<double>(nfft);
      for (long t = 0; t < nfft; ++t) {
        buf[static_cast<size_t>(t)] = (run.at(begin + t, ch) - mean) * window[static_cast<size_t>(t)];
      }
      fft.fwd(spec, buf);
      for (long b = 0; b < nb; ++b) cur(c, b) = spec[static_cast<size_t>(k_lo + b)];
    }
  };
  // Pass 1: the strongest window's instrument power per line.
  Eigen::VectorXd top_power = Eigen::VectorXd::Zero(nb);
  for (long k = 0; k < n_win; ++k) {
    transform(k, w0, w0 + nw);
    top_power = top_power.cwiseMax(cur.middleRows(w0, nw).colwise().squaredNorm().transpose());
  }
  // Pass 2: S = sum a a^H of all channels over all windows, the number of
  // windows that carry the excitation, L = sum w_{k+1} w_k^H of the
  // instruments over overlapping neighbours.
  std::vector<Eigen::MatrixXcd> s(static_cast<size_t>(nb), Eigen::MatrixXcd::Zero(na, na));
  Eigen::VectorXd excited_windows = Eigen::VectorXd::Zero(nb);
  std::vector<Eigen::MatrixXcd> lag(static_cast<size_t>(nb), Eigen::MatrixXcd::Zero(nw, nw));
  Eigen::MatrixXcd prev(nw, nb);
  for (long k = 0; k < n_win; ++k) {
    transform(k, 0, na);
    for (long b = 0; b < nb; ++b) {
      const auto bi = static_cast<size_t>(b);
      s[bi].selfadjointView<Eigen::Lower>().rankUpdate(cur.col(b));
      if (cur.col(b).segment(w0, nw).squaredNorm() >= kCoherenceWindowFraction * top_power(b)) {
        excited_windows(b) += 1.0;
      }
      if (follows[static_cast<size_t>(k)]) lag[bi] += cur.col(b).segment(w0, nw) * prev.col(b).adjoint();
    }
    prev = cur.middleRows(w0, nw);
  }
  for (auto& m : s) m = m.selfadjointView<Eigen::Lower>();

  // Lines with instrument power, in all and per instrument: every input
  // must be excited at a line for the MIMO solve there (a sweep that ends
  // early leaves the top of its input's band to leakage).
  std::vector<double> power(static_cast<size_t>(nb));
  std::vector<std::vector<double>> power_of(static_cast<size_t>(nw), std::vector<double>(static_cast<size_t>(nb)));
  for (long b = 0; b < nb; ++b) {
    for (Eigen::Index i = 0; i < nw; ++i) {
      const double p = s[static_cast<size_t>(b)](w0 + i, w0 + i).real();
      power_of[static_cast<size_t>(i)][static_cast<size_t>(b)] = p;
      power[static_cast<size_t>(b)] += p;
    }
  }
  const double max_power = *std::max_element(power.begin(), power.end());
  const double median_power = median_excited_power(power, kExcitedPowerFraction);
  std::vector<double> median_of(static_cast<size_t>(nw));
  for (Eigen::Index i = 0; i < nw; ++i)
    median_of[static_cast<size_t>(i)] = median_excited_power(power_of[static_cast<size_t>(i)], kExcitedPowerFraction);
  const bool with_sigma = n_win > n_in;
  frf_estimation::FrfAssembler out(plan, with_sigma, with_sigma);
  Eigen::MatrixXd sigma(n_out, n_in), coh(n_out, n_in);
  long unexcited = 0;
  for (long b = 0; b < nb; ++b) {
    const long bin = k_lo + b;
    const double f_hz = static_cast<double>(bin) * df;
    if (!(power[static_cast<size_t>(b)] > kExcitedPowerFraction * max_power)) {
      ++unexcited;
      continue;
    }
    if (power[static_cast<size_t>(b)] < kWeakLineFraction * median_power) {
      out.drop(f_hz, "the instrument has less than 1 % of its median power there");
      continue;
    }
    Eigen::Index weak = 0;
    while (weak < nw && power_of[static_cast<size_t>(weak)][static_cast<size_t>(b)] >=
                            kWeakLineFraction * median_of[static_cast<size_t>(weak)])
      ++weak;
    if (weak < nw) {
      out.drop(f_hz, "instrument " + run.channels[static_cast<size_t>(chans[static_cast<size_t>(w0 + weak)])].name +
                         " has less than 1 % of its median power there");
      continue;
    }
    const Eigen::MatrixXcd& sb = s[static_cast<size_t>(b)];
    const Eigen::MatrixXcd s_xw = sb.block(0, w0, n_out, nw);
    const Eigen::MatrixXcd s_fw = sb.block(n_out, w0, n_in, nw);
    const Eigen::MatrixXcd s_ww = sb.block(w0, w0, nw, nw);
    // Independence of the inputs' parts explained by the instruments:
    // rcond of S_fw S_ww^-1 S_wf scaled to unit diagonal, square-rooted to
    // compare with the periodic estimators' rcond of F.
    const Eigen::FullPivLU<Eigen::MatrixXcd> ww_lu(s_ww);
    double rcond = 0.0;
    if (ww_lu.rank() == nw) {
      Eigen::MatrixXcd m = s_fw * ww_lu.solve(s_fw.adjoint());
      const Eigen::VectorXd d = m.diagonal().real().cwiseMax(0.0).cwiseSqrt();
      if (d.minCoeff() > 0.0) {
        m = d.cwiseInverse().asDiagonal() * m * d.cwiseInverse().asDiagonal();
        const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd>(m).eigenvalues();
        rcond = std::sqrt(std::max(0.0, ev(0)) / ev(ev.size() - 1));
      }
    }
    if (rcond < options.min_rcond) {
      out.drop(f_hz, "the input cross-spectral matrix is singular");
      continue;
    }
    out.note_rcond(f_hz, rcond, options.warn_rcond);
    const Eigen::MatrixXcd g = s_fw.fullPivLu().inverse();
    Eigen::MatrixXcd h = s_xw * g;
    if (options.method == NonperiodicMethod::hv) {
      // Per output: null direction of [S_ff S_fx; S_xf S_xx] (Hermitian).
      Eigen::MatrixXcd c(n_in + 1, n_in + 1);
      for (int o = 0; o < n_out; ++o) {
        c.topLeftCorner(n_in, n_in) = sb.block(n_out, n_out, n_in, n_in);
        c.topRightCorner(n_in, 1) = sb.block(n_out, o, n_in, 1);
        c.bottomLeftCorner(1, n_in) = sb.block(o, n_out, 1, n_in);
        c(n_in, n_in) = sb(o, o);
        const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd> eig(c);
        const Eigen::VectorXcd v = eig.eigenvectors().col(0);
        if (std::abs(v(n_in)) == 0.0) continue;  // keep H1 for this output
        // [h, -1] z ~ 0 with a^H = v: h_i = -conj(v_i) / conj(v_n).
        for (int i = 0; i < n_in; ++i) h(o, i) = -std::conj(v(i)) / std::conj(v(n_in));
      }
    }
    // Residual power per output: e = x_o - H_o f = a^T z, sum |e|^2 = a^T S_zz conj(a).
    const double sign = (bin % 2 == 0) ? 1.0 : -1.0;
    const Eigen::VectorXd gain =
        (g.adjoint() * s_ww * g).diagonal().real() +
        2.0 * sign * rho * (g.adjoint() * lag[static_cast<size_t>(b)] * g).diagonal().real();
    const Eigen::MatrixXcd s_zz = sb.topLeftCorner(nz, nz);
    Eigen::VectorXcd a(nz);
    for (int o = 0; o < n_out; ++o) {
      a.setZero();
      a(o) = 1.0;
      a.tail(n_in) = -h.row(o).transpose();
      const double res = std::max(0.0, (a.transpose() * s_zz * a.conjugate())(0, 0).real());
      const double var_e = with_sigma ? res / static_cast<double>(n_win - n_in) : 0.0;
      for (int i = 0; i < n_in; ++i) {
        sigma(o, i) = std::sqrt(std::max(0.0, var_e * gain(i)));
        coh(o, i) = frf_estimation::coherence_from_sigma(h(o, i), sigma(o, i), excited_windows(b));
      }
    }
    out.add(f_hz, h, sigma, coh);
  }
  est.frf = out.finish(est.warnings, est.lines_dropped, "welch");
  est.lines_dropped += unexcited;  // expected: outside the excited band, not a warning
  est.averages = n_win;
  return est;
}

}  // namespace ambdiag
