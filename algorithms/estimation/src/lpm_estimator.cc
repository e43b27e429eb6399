// Chirp runs: the local polynomial method (LPM; R. Pintelon, J. Schoukens,
// G. Vandersteen, K. Barbé, "Estimation of nonparametric noise and FRF
// models for multivariable systems", Mech. Syst. Signal Process. 24, 2010)
// on the DFT of whole segments (rectangular window). A sweep excites each
// line once, while the response rings on: Welch windows cut that ringing
// short (biasing lightly damped resonances) and give almost no averages at a
// line. LPM instead models, around every line k, over the 2 W + 1 lines
// k + q of every segment s,
//
//   Z_s(k + q) = sum_d G_d (q / W)^d R_s(k + q) + sum_d T_sd (q / W)^d + E_s(k + q),
//
// d = 0..D: the response to the references as a polynomial G(k + q) and the
// transient (leakage: the ringing at the segment's ends) as a polynomial
// T_s, fitted by least squares for all measured channels Z = [x; f] at once.
// G_0 = [G_xr; G_fr] at line k; H = G_xr G_fr^-1 ((1) of frf_estimation.h:
// unbiased in closed loop); the residuals give the noise covariance C of Z
// with dof = rows - unknowns, and
//
//   sigma^2[o][i] = (a^T C conj(a)) (M^T P conj(M))_ii,
//
// a = [unit_o; -H(o,:)^T], M = G_fr^-1, P the G_0 block of (K^H K)^-1 of
// the regression matrix K.
#include <algorithm>
#include <cmath>
#include <complex>
#include <string>
#include <vector>

#include <unsupported/Eigen/FFT>

#include "ambdiag/core/error.h"
#include "frf_estimation_internal.h"

namespace ambdiag {

using frf_estimation::ChannelPlan;
using frf_estimation::median_excited_power;

namespace {

constexpr int kDegree = 2;  // D: polynomial degree of G and T
constexpr int kMinDof = 8;  // residual degrees of freedom per line, at least
constexpr double kExcitedPowerFraction = 1e-6;
constexpr double kWeakLineFraction = 1e-2;  // of the median excited line's reference power

}  // namespace

FrfEstimate estimate_lpm(const RunRecording& run, const ChannelPlan& plan,
                         const FrfEstimationOptions& options) {
  if (auto welch = welch_if_segments_differ(run, plan, options, "the local polynomial method")) return *welch;
  const Excitation& ex = *run.excitation;
  const int64_t n = ex.segments.front().length;
  FrfEstimate est;
  est.method = "lpm";
  const int n_out = plan.n_out(), n_in = plan.n_in(), n_seg = static_cast<int>(ex.segments.size());
  if (n < 64)
    throw InputError("excitation.segments: " + std::to_string(n) + " samples are too few for an FRF");
  frf_estimation::Windows segments;
  for (const auto& s : ex.segments) segments.push_back({s.start, s.start + s.length});
  frf_estimation::check_references(run, plan, segments);
  frf_estimation::check_clipping(run, plan, segments);

  const double fs = run.sample_rate_hz, df = fs / static_cast<double>(n);
  const double f_max = ex.f_max_hz > 0.0 ? ex.f_max_hz : fs / 2.0;
  const int64_t last = (n - 1) / 2;  // highest line below Nyquist
  const int64_t k_lo = std::max<int64_t>(1, static_cast<int64_t>(std::ceil(ex.f_min_hz / df - 1e-9)));
  const int64_t k_hi = std::min<int64_t>(static_cast<int64_t>(std::floor(f_max / df + 1e-9)), last);
  if (k_hi < k_lo) throw InputError("excitation: no line between f_min_hz and f_max_hz");

  // Unknowns per channel: G (n_in references) and T (one per segment), D + 1 each.
  const int unknowns = (n_in + n_seg) * (kDegree + 1);
  const int half = std::max(1, (unknowns + kMinDof - n_seg + 2 * n_seg - 1) / (2 * n_seg));  // W
  const int width = 2 * half + 1, rows = n_seg * width, dof = rows - unknowns;

  // Spectra of whole segments: z (outputs, inputs) and r, lines 0..last.
  const std::vector<int> zc = plan.measured_channels();
  const auto nz = static_cast<Eigen::Index>(zc.size());
  std::vector<Eigen::MatrixXcd> z(static_cast<size_t>(n_seg)), r(static_cast<size_t>(n_seg));
  {
    Eigen::FFT<double> fft;
    std::vector<double> buf(static_cast<size_t>(n));
    std::vector<std::complex<double>> spec;
    const auto transform = [&](int64_t start, int ch, Eigen::MatrixXcd& out, Eigen::Index row) {
      for (int64_t t = 0; t < n; ++t) buf[static_cast<size_t>(t)] = run.at(start + t, ch);
      fft.fwd(spec, buf);
      for (int64_t k = 0; k <= last; ++k) out(row, k) = spec[static_cast<size_t>(k)] / static_cast<double>(n);
    };
    for (int s = 0; s < n_seg; ++s) {
      const int64_t start = ex.segments[static_cast<size_t>(s)].start;
      z[static_cast<size_t>(s)].resize(nz, last + 1);
      r[static_cast<size_t>(s)].resize(n_in, last + 1);
      for (Eigen::Index c = 0; c < nz; ++c)
        transform(start, zc[static_cast<size_t>(c)], z[static_cast<size_t>(s)], c);
      for (int j = 0; j < n_in; ++j) {
        transform(start, plan.reference_channels[static_cast<size_t>(j)], r[static_cast<size_t>(s)], j);
      }
    }
  }

  // Excited lines, and the weak ones at a sweep's ends.
  std::vector<double> power(static_cast<size_t>(k_hi - k_lo + 1), 0.0);
  for (int64_t k = k_lo; k <= k_hi; ++k) {
    for (int s = 0; s < n_seg; ++s)
      power[static_cast<size_t>(k - k_lo)] += r[static_cast<size_t>(s)].col(k).squaredNorm();
  }
  const double max_power = *std::max_element(power.begin(), power.end());
  const double median_power = median_excited_power(power, kExcitedPowerFraction);
  // Local windows stay inside the excited band when it is wide enough.
  const int64_t band_lo = (k_hi - k_lo + 1 >= width) ? k_lo : 1;
  const int64_t band_hi = (k_hi - k_lo + 1 >= width) ? k_hi : last;
  if (band_hi - band_lo + 1 < width) {
    throw InputError("excitation.segments: " + std::to_string(n) +
                     " samples give too few lines for the local " + "polynomial method (" +
                     std::to_string(width) + " needed)");
  }

  frf_estimation::FrfAssembler out(plan, true, true);
  Eigen::MatrixXcd kmat(rows, unknowns), zmat(rows, nz);
  Eigen::MatrixXd sigma(n_out, n_in), coh(n_out, n_in);
  long unexcited = 0;
  for (int64_t k = k_lo; k <= k_hi; ++k) {
    const double f_hz = static_cast<double>(k) * df;
    const double p = power[static_cast<size_t>(k - k_lo)];
    if (!(p > kExcitedPowerFraction * max_power)) {
      ++unexcited;
      continue;
    }
    if (p < kWeakLineFraction * median_power) {
      out.drop(f_hz, "the references have less than 1 % of their median power there");
      continue;
    }
    const int64_t lo = std::clamp<int64_t>(k - half, band_lo, band_hi - width + 1);
    kmat.setZero();
    for (int s = 0; s < n_seg; ++s) {
      for (int q = 0; q < width; ++q) {
        const int64_t line = lo + q;
        const double x = static_cast<double>(line - k) / half;
        const Eigen::Index row = s * width + q;
        double xd = 1.0;
        for (int d = 0; d <= kDegree; ++d, xd *= x) {
          for (int j = 0; j < n_in; ++j)
            kmat(row, j * (kDegree + 1) + d) = xd * r[static_cast<size_t>(s)](j, line);
          kmat(row, (n_in + s) * (kDegree + 1) + d) = xd;
        }
        zmat.row(row) = z[static_cast<size_t>(s)].col(line).transpose();
      }
    }
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXcd> qr(kmat);
    if (qr.rank() < unknowns) {
      out.drop(f_hz, "the local regression is singular (references not independent there)");
      continue;
    }
    const Eigen::MatrixXcd theta = qr.solve(zmat);
    const Eigen::MatrixXcd res = zmat - kmat * theta;
    const Eigen::MatrixXcd c = res.transpose() * res.conjugate() / static_cast<double>(dof);
    const Eigen::MatrixXcd khk_inv = (kmat.adjoint() * kmat).inverse();
    Eigen::MatrixXcd g(nz, n_in), pm(n_in, n_in);
    for (int j = 0; j < n_in; ++j) {
      g.col(j) = theta.row(j * (kDegree + 1)).transpose();
      for (int j2 = 0; j2 < n_in; ++j2) pm(j, j2) = khk_inv(j * (kDegree + 1), j2 * (kDegree + 1));
    }
    const Eigen::MatrixXcd g_fr = g.bottomRows(n_in);
    const double rcond = frf_estimation::row_scaled_rcond(g_fr);
    if (rcond < options.min_rcond) {
      out.drop(f_hz, "the inputs' responses to the references are nearly dependent (singular G_fr)");
      continue;
    }
    out.note_rcond(f_hz, rcond, options.warn_rcond);
    const Eigen::MatrixXcd m = g_fr.inverse();
    const Eigen::MatrixXcd h = g.topRows(n_out) * m;
    const Eigen::VectorXd gain = (m.transpose() * pm * m.conjugate()).diagonal().real();
    Eigen::VectorXcd a(nz);
    for (int o = 0; o < n_out; ++o) {
      a.setZero();
      a(o) = 1.0;
      a.tail(n_in) = -h.row(o).transpose();
      const double v = std::max(0.0, (a.transpose() * c * a.conjugate())(0, 0).real());
      for (int i = 0; i < n_in; ++i) {
        sigma(o, i) = std::sqrt(std::max(0.0, v * gain(i)));
        coh(o, i) = frf_estimation::coherence_from_sigma(h(o, i), sigma(o, i), n_seg);
      }
    }
    out.add(f_hz, h, sigma, coh);
  }
  est.frf = out.finish(est.warnings, est.lines_dropped, "lpm");
  est.lines_dropped += unexcited;
  est.averages = n_seg;
  est.sigma_dof = 2 * dof;
  return est;
}

}  // namespace ambdiag
