// Diagnosis: fit every fault hypothesis to the measured change, score,
// rank, and decide whether the best one explains it (diagnosis.h).
#include "ambdiag/algorithms/diagnosis/diagnosis.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/core/error.h"
#include "diagnosis_internal.h"
#include "frf_fit_target.h"

namespace ambdiag {

using namespace diagnosis_detail;

bool DiagnosisOptions::is_valid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!(alpha > 0.0 && alpha < 0.5)) return fail("alpha must be in (0, 0.5)");
  if (crack_refine < 1) return fail("crack_refine must be >= 1");
  if (!(unexplained_share >= 0.0 && unexplained_share < 1.0)) return fail("unexplained_share must be in [0, 1)");
  return true;
}

DiagnosisResult diagnose(const PlantModel& plant, const ReferenceStatistics& reference, const FrfData& measured,
                         const DiagnosisOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InputError("diagnosis options: " + why);
  auto progress = [&](const std::string& stage, int done, int total) {
    if (options.progress) options.progress(stage, done, total);
  };
  const Aligned a = diagnosis_detail::align(reference, measured);
  DiagnosisResult res;
  diagnosis_detail::detect(a, options, res);
  res.not_assessed = {"unbalance: needs monitoring runs (1x bearing forces), none given",
                      "misalignment: needs monitoring runs (2x bearing forces), none given"};

  if (options.detect_only) return res;
  progress("nominal model", 0, 1);
  ModelGrid grid(plant, a);
  const FrfFitTarget target = make_target(a, grid);
  const FrfFitTarget plain{target.freq_hz, target.measured, target.weight, {}};
  Values healthy;  // the prediction of the healthy machine: the reference mean
  for (const auto& e : a.entries) healthy.push_back(e.mean);
  res.chi2_before = fit_chi2(plain, healthy);
  res.model_before = as_frf(grid.nominal(), a);
  res.nrmse_before = nrmse_of(grid.nominal(), a);
  res.chi2_after = res.chi2_before;
  res.nrmse_after = res.nrmse_before;
  res.model_after = res.model_before;
  if (!res.detected) {
    res.explained = true;
    res.evaluations = grid.evaluations();
    return res;
  }

  const std::vector<FaultHypothesis> hyps = fault_hypotheses(plant);
  std::vector<Screened> screened;
  std::vector<FaultEstimate> cands = fit_plant_faults(plant, hyps, grid, target, a, options, screened);
  progress("channel faults", 0, 1);
  const std::vector<FaultEstimate> channels = fit_channel_faults(plant, hyps, a, grid.nominal(), plain, 0.0);
  cands.insert(cands.end(), channels.begin(), channels.end());
  rank_faults(std::move(cands), hyps, screened, grid, a, options, res);
  res.evaluations = grid.evaluations();
  progress("done", 1, 1);
  return res;
}

}  // namespace ambdiag
