// What `ambdiag fit` prints and draws, shared with the server's analysis of
// every run (../shared/specs/cli.md, `fit` keys): the identified modes
// paired with the model's (the paper's Table 3) as JSON, and the
// stabilization diagram and a measured-vs-model Bode plot as SVG.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/identification/mode_labels.h"
#include "ambdiag/algorithms/identification/rational_fit.h"
#include "ambdiag/algorithms/model/modal_analysis.h"
#include "ambdiag/core/frf_data.h"

namespace ambdiag {

// cli.md's fit JSON: "order", "pole_pairs", "numerator_power", "modes"
// (sorted as paired), "fit" (chi2, convergence, delay), and with a model
// (`model_modes` not null) "unmatched_model_modes" and
// "unmatched_identified_modes"; "stabilization" when `with_stabilization`.
nlohmann::json fit_to_json(const RationalFitResult& fit, const ModePairing& pairing,
                           const std::vector<Mode>* model_modes, bool with_stabilization = true);

// Stabilization diagram: poles of every order over frequency, stable ones
// filled, the chosen order marked; the mean |H| underneath for orientation.
std::string stabilization_svg(const RationalFitResult& fit, const FrfData& frf);

// |H| and phase of up to `max_entries` entries of `measured` (the ones with
// the largest RMS first) with the model's on the same grid, dashed.
std::string bode_svg(const FrfData& measured, const FrfData& model, const std::string& title, int max_entries = 4);

}  // namespace ambdiag
