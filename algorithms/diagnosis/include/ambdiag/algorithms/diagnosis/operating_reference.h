// Detection under real operating conditions (issue 16, docs/diagnosis.md
// section 7): a pump never repeats its reference run. Its speed differs from
// run to run and its fluid-seal coefficients drift a few percent with
// temperature and flow; neither is a fault. So runs are compared with each
// other through the model, and the normal drift is a nuisance that is
// fitted per run and tested against what the reference runs showed.
//
// Model of run j (speed s_j, stated in its FRF file, else the plant's):
//   H_j = M(s_j, theta_j) + b + e_j
// M the plant model's FRF at speed s_j with the coefficients of every link
// of kind `seal` or `balance_piston` scaled by exp(theta_jk) (one log
// factor per link), b the model's own error (measured - model, the same at
// every run to first order), e_j the noise (sigma columns, times kappa).
//
// Learning from n >= 2 reference runs: theta_i fitted per run (LM, first
// with b = 0, so that b keeps only what no drift explains), b = mean_i (H_i
// - M(s_i, theta_i)) (two passes), theta_mean = mean_i theta_i; the normal
// spread of theta modelled as a common drift of all fluid links plus each
// link's own,
//   Sigma = sd_c^2 1 1^T + sd_l^2 I,
// with sd_c, sd_l estimated from the runs (pooled) but never below their
// floors (a few runs cannot estimate a spread; the floors are the physics:
// temperature and flow move seal coefficients by a few percent); kappa per
// entry from the pooled residual scatter, as reference_statistics.h, with
// the dof of estimated sigmas (`sigma_dof`) taken into account.
//
// Detection of run j: theta fitted (LM with Broyden updates, ~5 model FRFs),
//  - residual test: T = sum 2 |H - M(s, theta) - b|^2 / (u + v), chi2 with
//    2 N - K dof (Satterthwaite with an estimated sigma, as diagnosis.h):
//    any change the drift cannot produce;
//  - drift test: D = d^T ((1 + 1/n) Sigma + Cov)^-1 d, d = theta - theta_mean,
//    chi2 with K dof: a drift beyond the normal spread (a worn balance
//    piston changes only its link: beyond the per-link spread).
// Both are independent on the healthy machine (residual and estimate of a
// least-squares fit), each at alpha_each = 1 - sqrt(1 - alpha), so the
// false-alarm rate per run is alpha. Diagnosis (when detected) fits every
// fault hypothesis at the run's speed with the nuisance profiled out
// (linearised, with the prior of its normal spread), as diagnosis.h; the
// three best candidates fitted again jointly with the drift, exactly.
// Cost: detection ~16 ms CPU on the reference pump (~5 model FRFs),
// diagnosis 0.3-0.4 s (100-180 model FRFs).
#pragma once

#include <complex>
#include <string>
#include <vector>

#include "ambdiag/algorithms/diagnosis/diagnosis.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag {

// The false-alarm rate per run the server should use: at one run an hour
// (8766 runs a year) 0.09 false alarms per pump and year (docs/diagnosis.md).
inline constexpr double kRecommendedAlphaPerRun = 1e-5;

struct OperatingReferenceOptions {
  double common_sd_floor = 0.03;  // normal common drift of all fluid-seal links, sd of ln(factor)
  double link_sd_floor = 0.01;    // normal drift of each link on its own, sd of ln(factor)
  double log_factor_bound = 1.0;  // |ln(factor)| bound of the nuisance fits
  double alpha_scatter = 0.01;    // significance of "residual scatter exceeds sigma" (kappa)
  int passes = 2;                 // alternations of the bias b and the per-run fits
  bool is_valid(std::string* error) const;
};

struct OperatingRun {
  std::string run_id;              // metadata run_id, else "run <i>"
  double speed_rpm = 0.0;
  std::vector<double> log_factor;  // fitted theta per nuisance link (absolute, not centred)
  double chi2 = 0.0;               // sum |H - M(s, theta) - b|^2 / sigma^2 (E = values)
  int values = 0;
};

struct OperatingEntry {
  std::string output, input;
  std::vector<std::complex<double>> bias;  // b per line: mean of measured - model
  std::vector<double> sigma2;              // (1/n) sum_i sigma_i^2 per line (stated, without kappa)
  double kappa = 1.0;                      // factor on the stated variance
  double scatter_ratio = 1.0, scatter_p = 1.0;
};

struct OperatingReference {
  OperatingReferenceOptions options;
  std::vector<std::string> nuisance_links;  // names of the links of kind seal / balance_piston
  std::vector<double> freq_hz;
  std::vector<OperatingRun> runs;
  std::vector<double> log_factor_mean;      // theta_mean per link
  std::vector<double> log_factor_mean_cov;  // K x K, row-major: of theta_mean from the noise
  double common_sd = 0.0, link_sd = 0.0;    // used: max(estimate, floor)
  double common_sd_estimate = 0.0, link_sd_estimate = 0.0;  // from the runs alone
  // Real degrees of freedom of the entries' mean stated variance (sigma2),
  // n^2 / sum_i (1 / nu_i) from the runs' `sigma_dof`; 0: exact (none stated).
  double sigma2_dof = 0.0;
  std::vector<OperatingEntry> entries;
  const OperatingEntry* find(const std::string& output, const std::string& input) const;
};

// Learnt on the lines every run has (runs at other speeds drop other lines:
// the line a speed harmonic falls on). Throws InputError naming the run when
// runs are not on one grid (a line off it, or under 90 % of its lines
// common to all), disagree on entries, lack sigma columns, the model lacks
// a channel, or there are fewer than 2 runs. Cost: ~6 model FRFs per run and pass (~0.05 s CPU for three runs).
OperatingReference learn_operating_reference(const PlantModel& plant, const std::vector<FrfData>& runs,
                                             const OperatingReferenceOptions& options = {});

// The learnt reference as a JSON document (`ambdiag.operating_reference/1`)
// and back; from_json throws InputError naming the field of a bad document.
std::string operating_reference_to_json(const OperatingReference& reference);
OperatingReference operating_reference_from_json(const std::string& text);

// Detection at the measured run's speed (FrfData::speed_rpm, else the
// plant's) and, when detected and !options.detect_only, the ranked fault
// diagnosis with the faults evaluated at that speed. `statistic`,
// `threshold`, `dof` are those of the test with the smaller p-value;
// `p_value` = 1 - (1 - min(p_residual, p_drift))^2, so detected == (p_value
// < alpha); both tests and the nuisance estimates are in `operating`. The measured grid may
// differ from the references' within their range (b and its variance
// linearly interpolated). Throws InputError when the measured run shares no
// entry with the reference, lies outside its frequency range, the plant's
// fluid-seal links are not those of the reference, or it lacks sigma.
DiagnosisResult diagnose(const PlantModel& plant, const OperatingReference& reference, const FrfData& measured,
                         const DiagnosisOptions& options = {});

}  // namespace ambdiag
