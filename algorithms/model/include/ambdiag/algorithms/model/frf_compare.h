// Comparing a model's FRF matrix with a measured one: the figures that
// diagnosis (issue 6) and explain (issue 7) report and minimise.
//
// nrmse follows ../shared/specs/cli.md: the RMS of |H_model - H_measured|
// over all lines and entries present, divided by the RMS of |H_measured|.
// chi2 weights each line by the measurement's noise: sum |dH / sigma|^2,
// whose expectation is the number of lines when the model is right and the
// noise is complex Gaussian with standard deviation sigma.
#pragma once

#include <string>
#include <vector>

#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag {

struct FrfEntryComparison {
  std::string output, input;
  int lines = 0;
  double nrmse = 0.0;  // of this entry alone
  double chi2 = 0.0;   // NaN when the measurement has no sigma for this entry
};

struct FrfComparison {
  double nrmse = 0.0;  // over all compared entries and lines
  double chi2 = 0.0;   // sum over entries with sigma
  int chi2_lines = 0;  // lines that chi2 sums over (its expectation)
  std::vector<FrfEntryComparison> entries;  // in the measured file's order
};

// The model FRF on the measured file's grid and entries, at the speed the
// measured file states (else the plant's speed_rpm), as cli.md requires.
// Throws InputError naming an entry whose sensor or actuator the model lacks.
FrfData model_frf_like(const PlantModel& plant, const FrfData& measured,
                       const FrfSynthesisOptions& options = {FrfMethod::modal});

// Compares entries present in both (by output and input name) on the common
// grid. Throws InputError if the grids differ or no entry is shared.
FrfComparison compare_frf(const FrfData& model, const FrfData& measured);

}  // namespace ambdiag
