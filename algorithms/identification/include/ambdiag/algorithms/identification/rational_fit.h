// Identification of a matrix of FRFs by a rational model with one common
// set of poles (pole-residue form):
//
//   H_e(s) = sum_k [ r_ek / (s - p_k) + conj(r_ek) / (s - conj(p_k)) ] + d_e,  s = j w
//
// for every FRF entry e (real poles appear once, with real residues; d_e is
// a real upper residual). Mobility and accelerance are divided by (j w) and
// (j w)^2 first, so that one model form serves every quantity.
//
// Method: a linear start by relaxed vector fitting with common poles
// (Gustavsen & Semlyen 1999, Gustavsen 2006; residues eliminated per entry by
// QR as in Deschrijver et al. 2008), weighted by 1/sigma, then a maximum-
// likelihood refinement: Levenberg-Marquardt on the poles with the residues
// projected out (variable projection, Golub & Pereyra 1973, Kaufman's
// Jacobian), cost sum |(H_model - H_meas) / sigma|^2. The covariance of the
// poles is the inverse Gauss-Newton Hessian of that cost (scaled by the
// residual chi^2 per degree of freedom when the data carry no sigma).
#pragma once

#include <complex>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ambdiag/core/frf_data.h"

namespace ambdiag {

struct RationalModel {
  std::vector<std::complex<double>> poles;  // rad/s; Im > 0 for a conjugate pair, Im == 0 for a real pole
  Eigen::MatrixXcd residues;                // entries x poles
  Eigen::VectorXd direct;                   // entries
  double delay_s = 0.0;                     // pure delay: every entry times e^{-j w delay_s}
  std::complex<double> evaluate(int entry, double w_rad_per_s) const;
  int pair_count() const;
  int real_parameter_count() const;  // poles + residues + direct terms
};

struct RationalFitOptions {
  double f_min_hz = 0.0;  // band used for the fit (0: whole file)
  double f_max_hz = 0.0;
  int modes = 0;          // fixed number of pole pairs; 0: automatic order
  int max_modes = 30;     // upper limit of the automatic order search
  int vf_iterations = 12;
  int ml_iterations = 40;
  bool ml_refine = true;
  // Fit a pure delay e^{-j w tau} of the whole matrix (acquisition delay)
  // when a score test at tau = 0 finds one (5 sigma); it is not rational and
  // would otherwise be absorbed by spurious poles.
  bool estimate_delay = true;
  // Whether IsValid; message names the option.
  bool is_valid(std::string* error) const;
};

// One row of the stabilization diagram: the poles found at one order.
struct StabilizationRow {
  int modes = 0;
  std::vector<std::complex<double>> poles;
  std::vector<bool> stable;  // frequency and damping agree with the previous order
  double chi2_per_dof = 0.0;
  double criterion = 0.0;    // order-selection criterion (lower is better)
};

struct IdentifiedMode {
  double f_hz = 0.0;
  double zeta = 0.0;
  double f_sd_hz = 0.0;
  double zeta_sd = 0.0;
  std::complex<double> pole;
  int pole_index = -1;               // into RationalModel::poles
  double peak_snr = 0.0;             // largest |residue contribution| at resonance over the noise
                                     // (sigma, or the residual's robust scale where larger)
  double significance = 0.0;         // chi^2 increase (noise units) when the pole is removed
  int stable_orders = 0;             // orders of the stabilization diagram holding this pole
  std::vector<double> entry_weight;  // per entry: share of the mode's contribution (0..1)
};

struct RationalFitReport {
  bool converged = false;
  std::string stop_reason;
  int ml_iterations = 0;
  double cost_start = 0.0;  // weighted cost after the linear start
  double cost = 0.0;        // final weighted cost (chi^2 when sigma is given)
  double chi2_per_dof = 0.0;
  bool sigma_from_data = true;  // false: sigma estimated from the residual
  int data_points = 0;          // real data values used
  bool sigma_inflated = false;  // sigma scaled up by the local residual (model error above the noise)
  bool delay_fitted = false;    // a delay was found significant and fitted
  double delay_s = 0.0;         // fitted delay (0 when not fitted)
  double delay_sd_s = 0.0;
};

struct RationalFitResult {
  RationalModel model;
  std::vector<IdentifiedMode> modes;  // physical modes in the band, ascending f
  std::vector<StabilizationRow> stabilization;
  int selected_modes = 0;
  int numerator_power = 0;  // 0 compliance, 1 mobility, 2 accelerance
  std::vector<int> entries;  // FrfData entry index of each model entry
  RationalFitReport report;
};

// Fits the entries of `frf` that carry signal. Throws InputError on invalid
// options or data too short for the order; not converging is reported.
RationalFitResult fit_rational(const FrfData& frf, const RationalFitOptions& options = {});

}  // namespace ambdiag
