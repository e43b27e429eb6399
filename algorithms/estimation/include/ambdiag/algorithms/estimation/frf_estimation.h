// FRF matrix estimated from a time-domain run recording
// (../shared/specs/run-recording.md): H = output / input for every response
// channel (displacement, velocity or acceleration) over every input, with
// the standard deviation of each complex estimate (sigma) and a coherence.
//
// Inputs are the measured actuator forces (role force) when the run has
// them, else the references themselves. In an AMB the loop is closed: the
// measured forces respond to the motion, and their noise is fed back into
// the displacements, so regressing x on the measured f (H1) is biased. Every
// estimator below uses the noise-free references r as instruments instead:
//
//   H = S_xr S_fr^-1                                                    (1)
//
// where S_ab = sum_k a_k b_k^H over experiments k (periodic methods, whole
// sweeps) or windows k (Welch). The noise on x and f is uncorrelated with r,
// so E[S_xr] = H E[S_fr] and (1) is consistent whatever the feedback; with
// one experiment per input it reduces to H = X F^-1 on averaged spectra,
// whose errors-in-variables bias is O(sigma_F^2 / |F|^2 / M) for M
// averages. First-order error: dH = sum_k e_k g_k with the residual
// e_k = x_k - H f_k and g_k = r_k^H S_fr^-1, hence per entry
//
//   sigma^2[o][i] = sum_k var(e_k[o]) |g_k[i]|^2.                         (2)
//
//  - multisine: per segment, settle periods dropped, each remaining period's
//    DFT at the excited bins (reference energy between f_min_hz and
//    f_max_hz), averaged; experiments are the segments; var(e_k) from the
//    period-to-period covariance of [x; f], pooled over the segments,
//    divided by the segment's number of periods.
//  - stepsine: per segment, a single-bin DFT of the last meas_samples
//    (whole periods, no leakage); the segments at one frequency (one per
//    input) are the experiments; var(e_k) from the noise covariance of
//    [x; f] at the neighbouring, unexcited bins of the same windows.
//  - chirp (`gated`, the default): (1) on whole-sweep spectra, then the
//    impulse responses time-gated to where they have decayed into the
//    noise; sigma from the same gate placed in the noise-only part
//    (gated_estimator.cc). `lpm`: the local polynomial method on whole
//    sweeps (lpm_estimator.cc), unbiased too but keeps the whole record's
//    noise.
//  - random (and a chirp on request): Welch (Hann windows, 50 % overlap,
//    within segments); (1) over windows with the references as instruments
//    (`welch`), or H1 = S_xf S_ff^-1 (`h1`, biased in closed loop), or Hv,
//    the total least squares solution per output (`hv`).
//    var(e) = sum_k |e_k|^2 / (K - n_in), and (2) includes the correlation
//    of adjacent half-overlapping Hann windows (noise DFTs correlated by
//    (-1)^m / 6 at bin m). Windows shorter than a few decay times of the
//    impulse response bias resonances (truncated ringing).
//
// Coherence, for every method: coh = |H|^2 / (|H|^2 + n sigma^2), the
// inverse of Bendat & Piersol's sigma^2 = (1 - coh) |H|^2 / (n coh), with n
// the averages that carry the excitation (periods, Welch windows with at
// least 1 % of the line's strongest window's reference power, sweeps): the
// fraction of one average's response at that entry that is not noise, 0..1.
// For stationary random excitation this is the ordinary (one input) or
// multiple coherence; for the periodic methods, which average exact
// spectra, and for sweeps, which cross a line in one or two Welch windows,
// the ordinary coherence is undefined or diluted by unexcited windows.
//
// References: J. S. Bendat, A. G. Piersol, Random Data, 4th ed., Wiley 2010,
// ch. 9 (random errors of H1 and coherence); R. Pintelon, J. Schoukens,
// System Identification: a frequency domain approach, 2nd ed., Wiley 2012,
// ch. 2 and 7 (periodic excitation, closed loop, sample variance, local
// polynomial method); A. Farina, AES preprint 5093, 2000 (sweep
// deconvolution and gating).
#pragma once

#include <string>
#include <vector>

#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/run_recording.h"

namespace ambdiag {

// The estimator for chirp and random runs; the periodic methods always
// solve (1). automatic: gated for a chirp, welch for random excitation.
enum class NonperiodicMethod { automatic, gated, lpm, welch, h1, hv };

struct FrfEstimationOptions {
  NonperiodicMethod method = NonperiodicMethod::automatic;
  // Welch window length in samples (even, >= 4; Welch only); 0 chooses the
  // largest power of two, 64..65536, that gives at least 15 half-overlapping
  // windows for random excitation, 7 for a chirp (whose lines are each
  // excited once, so long windows that hold the ringing matter more than
  // averages).
  long nfft = 0;
  // Lines where the input spectra of the experiments (rows scaled to unit
  // norm) have a reciprocal condition number below this are dropped (with a
  // warning); below `warn_rcond` they are kept and counted in a warning.
  double min_rcond = 1e-7;
  double warn_rcond = 1e-3;

  // Empty if valid, else what is wrong (names the option).
  std::string invalid_reason() const;
};

struct FrfEstimate {
  FrfData frf;         // metadata: pump_id, run_id, speed_rpm, quantity, unit, method, averages, sigma_dof, warning_N
  std::string method;  // multisine, stepsine, gated, lpm, welch-ref, welch-h1, welch-hv
  std::vector<std::string> warnings;  // what a user should know: dropped lines, segments, no sigma
  long averages = 0;                  // periods (per experiment, mean), sweeps or Welch windows
  // Real degrees of freedom of sigma^2 per line (metadata `sigma_dof`; 0:
  // not known, e.g. overlapping Welch windows): 2 x the complex degrees of
  // freedom of the noise covariance (multisine: periods - 1 pooled over the
  // segments, less what the synchronous fit takes, median over the lines;
  // LPM residuals; step-sine: the noise bins pooled at a line, fewest).
  long sigma_dof = 0;
  long lines_dropped = 0;             // including lines without excitation in [f_min_hz, f_max_hz]
};

// Throws InputError (naming the channel, segment or line) for a run that
// gives no trustworthy estimate: no excitation, no reference or response
// channels, a reference that is zero, a clipped input or response channel,
// fewer independent experiments than inputs at every line, no excited line.
// Partial problems (a zero segment, a missing step, an ill-conditioned line,
// one usable period so no sigma) are warnings in the result.
FrfEstimate estimate_frf(const RunRecording& run, const FrfEstimationOptions& options = {});

}  // namespace ambdiag
