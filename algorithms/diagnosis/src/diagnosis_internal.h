// Private to the diagnosis: the measured FRF aligned with the reference
// statistics, entry by entry, with the variances the tests weight by, and
// the fitting of fault hypotheses to the measured change (diagnosis_fit.cc),
// shared by the same-speed and the operating-reference diagnosis.
#pragma once

#include <complex>
#include <deque>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ambdiag/algorithms/diagnosis/diagnosis.h"
#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "frf_fit_target.h"

namespace ambdiag::diagnosis_detail {

using Values = std::vector<std::vector<std::complex<double>>>;

struct AlignedEntry {
  std::string output, input;
  std::vector<std::complex<double>> h;     // measured
  std::vector<std::complex<double>> mean;  // reference mean
  std::vector<double> var;                 // of H - mean: u + v
  // Moments of t = 2 |H - mean|^2 / var per line on the healthy machine:
  // 2 and 4 when var is known, more when u rests on a sigma estimated with
  // few degrees of freedom (align()).
  std::vector<double> t_mean;
  double t_var = 0.0;  // summed over the lines
};

struct Aligned {
  std::vector<double> freq_hz;
  double speed_rpm = 0.0;
  std::vector<AlignedEntry> entries;
  // Real parameters fitted to the measurement before the test (the
  // operating reference's nuisance): each lowers E T by 1 and var T by 2.
  int fitted_dof = 0;
  int values() const;  // complex values (entries x lines)
  double t_mean() const;  // expected detection statistic on the healthy machine
};

Aligned align(const ReferenceStatistics& ref, const FrfData& measured);

// Detection test, symptoms and the pattern isolation; fills those fields.
void detect(const Aligned& a, const DiagnosisOptions& options, DiagnosisResult& result);

// Real degrees of freedom of the measured sigma^2 (metadata `sigma_dof`);
// infinity when the file states none. Throws InputError when unreadable or
// <= 4.
double sigma_dof(const FrfData& measured);
// Mean and variance of t = 2 |dH|^2 / (u_hat + v) per line, phi = u / (u + v)
// the estimated share of the variance, nu the dof of u_hat.
void t_moments(double phi, double nu, double& mean, double& var);

// The model side of the fit: the nominal FRF on the measured grid and speed
// and a way to evaluate a hypothesis at a parameter value (remembered, so
// that the screening probe is not computed twice). Modal synthesis on the
// Krylov basis with banded structural damping: ~3x cheaper than all
// eigenvalues, and healthy and faulty model use the same one, so its small
// error cancels in the change H(p) - H(nominal). `transform`, when given,
// is applied to every evaluated FRF (the operating reference's nuisance
// profile, which may append rows).
class ModelGrid {
 public:
  ModelGrid(const PlantModel& plant, const Aligned& a, std::function<void(Values&)> transform = {});
  Values raw(const PlantModel& p);  // without the transform
  Values evaluate(const PlantModel& p);
  const Values& evaluate(const FaultHypothesis& h, size_t id, double x);
  const Values& nominal() const { return nominal_; }
  int evaluations() const { return evaluations_; }

 private:
  const PlantModel& plant_;
  std::function<void(Values&)> transform_;
  FrfData skeleton_;
  FrfSynthesisOptions options_;
  Values nominal_;
  std::map<size_t, std::deque<std::pair<double, Values>>> cache_;
  int evaluations_ = 0;
};

// The weighted target: measured, 1 / sigma, and the offset (reference mean
// - nominal model) that turns a model into the prediction
// m + H(p) - H(nominal).
FrfFitTarget make_target(const Aligned& a, const ModelGrid& g);

// Where the screening evaluates each kind.
double probe_value(const FaultHypothesis& h);

// One hypothesis after screening: the chi2 drop that the secant from the
// nominal model to the probe promises (linearised).
struct Screened {
  size_t id = 0;
  double probe = 0.0;
  double drop = 0.0;
  double x_lin = 1.0;  // the linearised estimate
  double chi2 = 0.0;   // lowest chi2 seen (probe, and x_lin once evaluated)
};

struct Fitted {
  double x = 1.0;
  double sd = 0.0;
  double chi2 = 0.0;
};

Screened screen(const FaultHypothesis& h, size_t id, ModelGrid& g, const FrfFitTarget& t);
// Start values tried before refining (the chi2 of a resonance shift is not
// convex in a stiffness or seal factor).
std::vector<double> start_grid(const FaultHypothesis& h);
// The secant between two evaluated points as a Jacobian of the real
// weighted residual.
Eigen::MatrixXd secant(const Values& v1, double x1, const Values& v0, double x0, const FrfFitTarget& t);
// Best start, then Levenberg-Marquardt with Broyden updates.
Fitted refine(const FaultHypothesis& h, const Screened& s, ModelGrid& g, const FrfFitTarget& t);
// NRMSE of the first a.entries.size() rows of `model` against the measured.
double nrmse_of(const Values& model, const Aligned& a);
std::string location_of(const FaultHypothesis& h, const PlantModel& plant, FaultEstimate& f);
FrfData as_frf(const Values& v, const Aligned& a);

// Screens every plant hypothesis, refines the non-crack ones and the best
// crack elements (options.crack_refine); the candidates, unscored.
std::vector<FaultEstimate> fit_plant_faults(const PlantModel& plant, const std::vector<FaultHypothesis>& hyps, ModelGrid& grid,
                                            const FrfFitTarget& target, const Aligned& a, const DiagnosisOptions& options,
                                            std::vector<Screened>& screened);
// Channel gains on a row / column of the healthy prediction (a.entries[].mean),
// closed form; `pure_model` scaled alike gives the NRMSE; extra_chi2 is
// added to each candidate's chi2 (a penalty the healthy prediction carries).
std::vector<FaultEstimate> fit_channel_faults(const PlantModel& plant, const std::vector<FaultHypothesis>& hyps, const Aligned& a,
                                              const Values& pure_model, const FrfFitTarget& plain, double extra_chi2);
// BIC scores, ranking, `explained`, the best model's FRF, `unknown` when
// nothing explains the change; needs res.threshold and res.chi2_before.
void rank_faults(std::vector<FaultEstimate> cands, const std::vector<FaultHypothesis>& hyps,
                 const std::vector<Screened>& screened, ModelGrid& grid, const Aligned& a, const DiagnosisOptions& options,
                 DiagnosisResult& res);

}  // namespace ambdiag::diagnosis_detail
