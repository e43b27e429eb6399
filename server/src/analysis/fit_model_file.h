// The modal fit of an analysis kept as data ("fit_model.json", beside its
// frf.csv): the rational model in pole-residue form (rational_fit.h), a few
// kB instead of a second FRF file of 2 MB per run. Evaluated again on the
// run's grid on request (GET /api/v1/runs/{run_id}/fit_frf.csv), so the web
// UI draws the fit over the measured FRF and the model's.
//
//   {"format": "ambdiag.fit_model/1", "quantity": "compliance",
//    "numerator_power": 0, "delay_s": 0,
//    "poles_rad_per_s": [[re, im], ...],           // Im > 0: a conjugate pair
//    "entries": [{"output", "input", "direct", "residues": [[re, im], ...]}]}
//
// H_e(jw) = (jw)^p e^{-jw delay} [d_e + sum_k r_ek/(jw - p_k) + conj(r_ek)/(jw - conj(p_k))]
// (the conjugate term only for complex poles), p = numerator_power.
#pragma once

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/identification/rational_fit.h"
#include "ambdiag/core/frf_data.h"

namespace ambdiag::server::detail {

// The fit of `frf` (the FRF it was fitted to: its entry names) as the document above.
nlohmann::json fit_model_json(const RationalFitResult& fit, const FrfData& frf);

// The fit's FRF on the frequency grid of `grid`, one entry per entry of the
// model, with `grid`'s quantity and unit. Throws InputError naming the key
// when `model` is not such a document.
FrfData fit_frf_like(const nlohmann::json& model, const FrfData& grid);

}  // namespace ambdiag::server::detail
