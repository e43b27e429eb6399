// The computations behind the server's jobs, free of storage and threads:
// what one analysis, one reference and one explain job compute from their
// inputs, as the result JSON and the files kept with it (rest.md,
// "Analysis, without being asked"; docs/service.md).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/diagnosis/operating_reference.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/run_recording.h"
#include "ambdiag/storage/service.h"

namespace ambdiag::server::detail {

// Called with the share done (0..1); may be empty.
using ProgressFn = std::function<void(double)>;

struct JobOutput {
  nlohmann::json result = nlohmann::json::object();
  std::vector<storage::JobArtifact> artifacts;
};

// The plant of a stored model version (the plant JSON, with or without
// explain's "acquisition" extension). Throws InputError naming the field.
PlantModel plant_from_text(const std::string& plant_json, const std::string& source);

// The FRF estimate of an identification run with its sigma, as analysis and
// reference jobs share it. Throws InputError naming the run and what is wrong.
FrfData estimate_run_frf(const RunRecording& run, nlohmann::json* summary);

// One run: FRF estimate with sigma ("frf.csv"), modal fit labelled against
// the model at the run's speed ("stabilization.svg"), measured vs model
// ("bode.svg"), and with a reference, detection and (when it fires) the
// diagnosis ("diagnosis.svg"). Result keys: speed_rpm, frf, modes, fit,
// unmatched_model_modes, unmatched_identified_modes, nrmse, detection,
// diagnosis (null where not computed).
JobOutput analyse_run(const PlantModel& plant, const RunRecording& run, const OperatingReference* reference,
                      double alpha, const ProgressFn& progress);
// The same from an FRF already estimated (the frf.csv an earlier analysis
// kept, when retention dropped the samples): `run` needs its header only
// (run id, speed, channels); `frf_summary` becomes the result's "frf".
JobOutput analyse_frf(const PlantModel& plant, const RunRecording& run, FrfData frf, nlohmann::json frf_summary,
                      const OperatingReference* reference, double alpha, const ProgressFn& progress);

// A reference from the FRFs of its runs ("reference.json").
JobOutput learn_reference(const PlantModel& plant, const std::vector<FrfData>& frfs,
                          const std::vector<std::string>& run_ids, const ProgressFn& progress);

// Explain the run's FRF against the model: cli.md's explain JSON, the
// improved model ("improved_model.json") and its figure ("explain.svg").
JobOutput explain_run(const PlantModel& plant, const FrfData& frf, const ProgressFn& progress);

}  // namespace ambdiag::server::detail
