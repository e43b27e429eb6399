// The `diagnose` JSON of ../shared/specs/cli.md, shared by the command line
// and the server's analysis of every run: detection, symptoms, ranked
// faults with parameters, intervals and locations, the fit before and after.
#pragma once

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/diagnosis/diagnosis.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag {

nlohmann::json diagnosis_to_json(const DiagnosisResult& result, const PlantModel& plant);
// The operating tests (DiagnosisResult::operating, when used): the run's
// speed, residual and drift test, the fitted seal factors; also the server's
// detection of every run, detected or not, so a healthy run shows its drift.
nlohmann::json operating_tests_to_json(const OperatingTests& tests);

// The tests of detection under operating conditions (operating_reference.h):
// the run's speed, the residual and drift tests, and per fluid-seal link the
// drift fitted ("factor", "log_factor", "sd") against its normal spread.
nlohmann::json operating_tests_to_json(const OperatingTests& tests);

}  // namespace ambdiag
