// The model's and the modal fit's FRF of an analysed run as data, for the
// web UI's Bode plot over the measured FRF (GET
// /api/v1/runs/{run_id}/model_frf.csv and .../fit_frf.csv).
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

// The FRF file of the modal fit of the run's current analysis (its
// fit_model.json, fit_model_file.h) on the grid of its frf.csv, for the
// entries the fit used. NotFoundError as model_frf_csv, and for an analysis
// made before fit_model.json was kept.
std::string fit_frf_csv(storage::Historian& h, const std::string& run_id);

}  // namespace ambdiag::server::detail
