// Fault detection and model-based diagnosis (Nordmann & Aenis 2004, and
// ../shared/specs/cli.md `diagnose`): is the measured FRF matrix of the
// machine still that of the healthy machine, and if not, which fault model
// (fault_models.h), where and how large, explains the change?
//
// Detection. With the reference statistics (reference_statistics.h), mean m
// and variance of the mean v, and the measured H with variance u (its
// sigma columns scaled by the references' kappa), the statistic
//   T = sum_{entries, lines} 2 |H - m|^2 / (u + v)
// is chi2 with 2 x (entries x lines) degrees of freedom on the healthy
// machine; detected when T > chi2_quantile(1 - alpha, dof), so the
// false-alarm rate is alpha. When the measured file states the degrees of
// freedom nu of its sigma^2 (metadata `sigma_dof`, docs/formats.md), each
// term is 2 F(2, nu_eff) instead of chi2_2 (E = 2 nu / (nu - 2): an
// estimated sigma makes T larger) and T is tested as the scaled chi2 g
// chi2_h with its mean and variance (Satterthwaite); `dof` is then h. Per-entry tests (Bonferroni, alpha / entries)
// and per-row / per-column shares of the excess give the symptoms and the
// isolation of additive (one sensor row or actuator column) from
// multiplicative (the plant) changes.
//
// Diagnosis. Every fault hypothesis predicts the measured FRF as
//   P(p) = m + (H_model(p) - H_model(nominal))
// (the change the fault model makes, added to the healthy machine as
// measured, so that the model's own error cancels to first order; sensor and
// actuator faults scale a row / column of m by a gain). Every plant
// hypothesis is first screened by one model evaluation at a probe value
// (the secant from the nominal model gives the linearised chi2 drop); all
// non-crack hypotheses and the crack elements with the largest drop are
// then refined by Levenberg-Marquardt with Broyden updates
// (numerics/least_squares.h, weights 1 / sqrt(u + v)), about one evaluation per
// iteration; channel gains are linear and solved in closed form.
// Scores: BIC = 2 chi2 +
// k ln(N) + 2 ln(alternatives) (N real data values, k = 1 parameter,
// `alternatives` locations searched for that kind); the score reported is
// the posterior weight exp(-BIC / 2) normalised over the candidates. The
// best candidate explains the change when its chi2 (sum |r / sigma|^2 over
// N complex values, E = N on the healthy machine) falls to
//   chi2_after <= q_{1-alpha} + unexplained_share x (chi2_before - N)
// (q the detection threshold in these units): at the noise floor, up to a
// small share of the change that a fault model may miss; else the
// diagnosis is `unknown`, listed first.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "ambdiag/algorithms/diagnosis/fault_models.h"
#include "ambdiag/algorithms/diagnosis/reference_statistics.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag {

struct DiagnosisOptions {
  double alpha = 0.01;                // false-alarm rate of the detection test
  // Crack elements refined after screening. The screening's linearised
  // estimate ranks a big crack's element (EI x 0.5) up to 6th behind its
  // neighbours on a longer shaft (tests/support/second_pump.h: 8 of 21
  // misplaced with 3, none with 6, for 10 % more model evaluations).
  int crack_refine = 6;
  double unexplained_share = 0.05;    // share of the change's chi2 excess the best candidate may leave
  bool detect_only = false;           // stop after detection (no fault models fitted)
  // Called with a stage description and done/total counts (may be empty).
  std::function<void(const std::string& stage, int done, int total)> progress;
  bool is_valid(std::string* error) const;
};

struct Symptom {
  std::string kind;           // "entry", "sensor_row", "actuator_column", "band"
  std::string output, input;  // the entry, or the channel of a row / column
  double statistic = 0.0;     // chi2 of the residual over its lines (entry), or share of the excess (row, column, band)
  double dof = 0.0;
  double p_value = 1.0;
  double band_lo_hz = 0.0, band_hi_hz = 0.0;
};

struct FaultEstimate {
  FaultHypothesis hypothesis;
  std::string name;          // to_string(kind), or "unknown"
  std::string location;      // e.g. "element 8", "link balance_piston", "sensor xBy"; empty: none
  double z_lo_m = 0.0, z_hi_m = 0.0;  // axial extent of a shaft location
  double value = 0.0;        // the parameter's estimate
  double sd = 0.0;           // its standard deviation (LM covariance)
  double ci_lo = 0.0, ci_hi = 0.0;    // 95 % interval, clipped to the bounds
  double coefficient_factor = 1.0;    // seal faults: factor on the link coefficients
  double chi2 = 0.0;         // sum |residual / sigma|^2 over all lines and entries
  double bic = 0.0;
  double score = 0.0;        // posterior weight among the candidates (0..1)
  double nrmse = 0.0;        // pure model (fault applied) vs measured
  int evaluations = 0;       // model FRF evaluations spent on it
};

// A fitted nuisance parameter of the operating-reference detection
// (operating_reference.h): the log factor on one fluid-seal link's
// coefficients, relative to the reference runs' mean state.
struct NuisanceEstimate {
  std::string link;         // link name
  double log_factor = 0.0;  // ln(coefficient factor) - the references' mean
  double sd = 0.0;          // of the estimate (noise)
  double normal_sd = 0.0;   // the learnt run-to-run spread (with its floor)
};

// The two tests of the operating-reference detection; empty (used = false)
// for the same-speed path. DiagnosisResult's statistic, threshold and dof
// are those of the test with the smaller p-value (both at alpha_each), so
// that detected == statistic > threshold still holds.
struct OperatingTests {
  bool used = false;
  double speed_rpm = 0.0;         // where the model was evaluated
  double alpha_each = 0.0;        // per test, 1 - sqrt(1 - alpha)
  double residual_statistic = 0.0, residual_threshold = 0.0, residual_dof = 0.0, residual_p_value = 1.0;
  bool residual_detected = false;
  double drift_statistic = 0.0, drift_threshold = 0.0, drift_p_value = 1.0;
  int drift_dof = 0;
  bool drift_detected = false;
  std::vector<NuisanceEstimate> nuisance;
};

struct DiagnosisResult {
  bool detected = false;
  double statistic = 0.0, threshold = 0.0, dof = 0.0, p_value = 1.0, alpha = 0.0;
  std::vector<Symptom> symptoms;  // significant entries (largest first), row/column shares, bands
  std::string isolation;          // "none", "multiplicative", "additive_sensor", "additive_actuator"
  std::vector<FaultEstimate> faults;  // best first; "unknown" first when nothing explains the change
  bool explained = false;
  double chi2_before = 0.0, chi2_after = 0.0;  // healthy prediction, best candidate (all lines)
  double nrmse_before = 0.0, nrmse_after = 0.0;  // pure nominal model / best fault model vs measured
  FrfData model_before, model_after;  // on the measured grid, for plots
  std::vector<std::string> not_assessed;  // faults without the data they need, with the reason
  int evaluations = 0;
  OperatingTests operating;  // filled by diagnose(plant, OperatingReference, ...)
};

// Throws InputError if the measured FRF is on another grid or speed than
// the references, lacks their entries, or the model lacks its channels.
DiagnosisResult diagnose(const PlantModel& plant, const ReferenceStatistics& reference, const FrfData& measured,
                         const DiagnosisOptions& options = {});

// Measured vs model before and after (|H| and phase of the entries that
// changed most), as an SVG document.
std::string diagnosis_svg(const DiagnosisResult& result, const FrfData& measured, int max_entries = 3);

}  // namespace ambdiag
