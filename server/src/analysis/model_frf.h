// The model's FRF of an analysed run as data, for the web UI's Bode plot
// over the measured FRF (GET /api/v1/runs/{run_id}/model_frf.csv).
#pragma once

#include <string>

#include "ambdiag/storage/historian.h"

namespace ambdiag::server::detail {

// The FRF file (frf-file.md) of the model version the run's current
// analysis used, on the grid and entries of that analysis' frf.csv at the
// run's speed (as bode.svg draws it): computed on request, not stored, so
// it costs no space per run. Throws NotFoundError for an unknown run or one
// without a finished analysis.
std::string model_frf_csv(storage::Historian& h, const std::string& run_id);

}  // namespace ambdiag::server::detail
