// Explaining the mismatch between a plant model and a measured FRF matrix
// (`ambdiag explain`, ../shared/specs/cli.md): where they differ beyond the
// noise, which existing parameters are off, which physics the model lacks,
// the improved model, and the fit before and after.
//
// Method (docs/explain.md):
//  1. Locate. Weighted residual r = (H_model - H_meas) / sigma per entry and
//     line; |r|^2 ~ Exp(1) when the model is right. A band is a run of lines
//     whose 9-line moving mean of |r|^2 exceeds 4 (for a right model that
//     mean is Gamma(9, 1/9): P(> 4) < 1e-8 per window, < 1e-3 over 25 entries
//     x 10^4 lines), widened by the window and merged across entries that
//     overlap in frequency. Each band is classified (plane, direction,
//     radial/axial, direct/cross) and given a kind from the residual's shape.
//  2. Select. Lines are split: even lines fit, odd lines validate. Greedy
//     forward selection, first over updates of existing parameters within
//     bounds, then over the physics library (missing_physics.h); a step
//     accepts the candidate (or, when no single one pays, the best pair of
//     the top singles) whose fit lowers chi2 on BOTH halves by more than a
//     penalty per parameter: ln(n) / 2 (BIC in chi2 units, n = real data
//     values) plus a 0.2 % of the current chi2 that absorbs model-form
//     differences between simulators. Finally all selected parameters are
//     refitted together and any update whose removal costs less than its
//     penalty is dropped.
//     The guarantee (chi2 weighs by 1 / sigma^2, the NRMSE of cli.md does
//     not): a step that raises the NRMSE beyond what the noise explains is
//     refused and the step tried without it; at the end the pieces, in the
//     order chosen and with their final values, must each lower the NRMSE
//     of the model built so far (a piece that does not is not handed out),
//     and each explanation reports its before and after in that chain. So
//     the improved model never fits worse than the nominal; with no piece
//     left nothing is explained, the reason in the story and on the
//     unexplained bands.
//  3. Report. What bands remain beyond noise with the final model are
//     `unexplained`; NRMSE per entry and overall before and after; the
//     noise-floor NRMSE sqrt(sum sigma^2 / sum |H|^2).
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/explain/missing_physics.h"
#include "ambdiag/algorithms/model/modal_analysis.h"
#include "ambdiag/algorithms/model/plant_frf_fit.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag {

struct ExplainOptions {
  int max_steps = 14;                    // selection steps (updates + physics)
  double window_threshold = 4.0;         // band rule: 9-line mean of |r|^2 above this
  double relative_penalty = 0.002;       // of the current chi2, per accepted step
  int rotor_candidates_fitted = 1;       // FE updates and FE physics fitted fully per step (after screening)
  int lowrank_fitted = 4;                // per step, updates and physics fitted on the low-rank model (explain_screen.h)
  std::function<void(const std::string&)> progress;  // one line per stage; may be empty
};

// A frequency band where model and measurement differ beyond the noise.
struct Mismatch {
  std::vector<std::string> outputs, inputs;  // sensors and actuators of the entries involved
  std::vector<std::string> entries;          // "xAx/fAy"
  double band_lo_hz = 0.0, band_hi_hz = 0.0;
  double chi2_per_line = 0.0;                // mean |r|^2 over the band's entries and lines
  std::string kind;  // extra_resonance, shifted_resonance, damping_change, phase_drift, cross_asymmetry,
                     // anti_resonance_moved, level_change
  nlohmann::json classification;             // planes, directions, radial/axial, direct/cross counts
  std::optional<nlohmann::json> mode;        // nearest model mode (label, f_hz, zeta) in the band
  // Unexplained bands: where and what, when a resonant attachment (not in
  // the catalogue; missing_physics.h) locates the extra mode.
  std::optional<nlohmann::json> located;
  std::string evidence;
};

struct Explanation {
  std::string physics;
  nlohmann::json parameters, location, sd;
  // Whole matrix, the final pieces chosen before it without and with it
  // (the guarantee above: after < before).
  double nrmse_before = 0.0, nrmse_after = 0.0;
  double chi2_drop_fit = 0.0, chi2_drop_validation = 0.0, penalty = 0.0;
  std::string evidence;
  // Other physics this recording cannot tell apart from this one (fitted in
  // its place, chi2 within 2 ln 100 on a half): {physics, parameters,
  // location, chi2_difference {fit, held_out}, evidence}.
  nlohmann::json alternatives = nlohmann::json::array();
  // With recordings at other speeds: how this claim predicts them
  // ({"chi2_per_line": [...], "speed_exponent"?}), and the physics they
  // ruled out ({physics, parameters, location, chi2_difference, evidence}).
  nlohmann::json other_speeds = nullptr;
  nlohmann::json refuted = nlohmann::json::array();
};

struct EntryFit {
  std::string output, input;
  double nrmse_before = 0.0, nrmse_after = 0.0, noise_floor = 0.0;
  double chi2_per_line_before = 0.0, chi2_per_line_after = 0.0;
};

struct ModePair {
  std::string label;
  double model_f_hz = 0.0, model_zeta = 0.0;
  double improved_f_hz = 0.0, improved_zeta = 0.0;  // NaN: missing in the improved model
  std::string status;  // paired, shifted, damping_changed, extra (only in improved), missing
  std::string direction, whirl;
};

// The improved model against a recording at another speed (explain with
// other_speeds; explain_speeds.h): does the explanation hold there too?
struct SpeedCheck {
  double speed_rpm = 0.0;
  double nrmse_before = 0.0, nrmse_after = 0.0, noise_floor_nrmse = 0.0;
  double chi2_per_line_before = 0.0, chi2_per_line_after = 0.0;
  std::vector<Mismatch> unexplained;  // bands beyond noise there with the improved model
};

struct ExplainResult {
  std::vector<Mismatch> mismatches;
  std::vector<Explanation> explanations;
  std::vector<Mismatch> unexplained;
  std::vector<ParameterChange> updated_parameters;
  std::vector<EntryFit> entries;
  std::vector<ModePair> modes;
  std::vector<SpeedCheck> other_speeds;  // one per recording at another speed
  double nrmse_before = 0.0, nrmse_after = 0.0, noise_floor_nrmse = 0.0;
  double chi2_per_line_before = 0.0, chi2_per_line_after = 0.0;
  PlantVariant improved;
  FrfData model_before, model_after;  // on the measured grid
  int rotor_solves = 0, evaluations = 0;
  std::vector<std::string> story;  // plain sentences for the text output
};

// Throws InputError when the measurement and the model do not fit together
// (an entry names a sensor/actuator the model lacks).
ExplainResult explain(const PlantModel& nominal, const FrfData& measured, const ExplainOptions& options = {});
// The same, with recordings of the machine at other speeds (each stating its
// speed_rpm): the explanation is chosen on `measured`; the others decide
// between physics one speed cannot tell apart (the claim or an alternative
// that predicts them decisively worse is ruled out), give a seal
// cross-coupling its speed law, and show whether the improved model holds
// at their speeds (other_speeds). Throws InputError for a recording without
// speed_rpm or at the primary's speed.
ExplainResult explain(const PlantModel& nominal, const FrfData& measured, const std::vector<FrfData>& other_speeds,
                      const ExplainOptions& options = {});

// Locating alone (step 1) for a model's FRF against the measurement.
// `model_modes` (modal_analysis of the plant) name the mode behind a band.
std::vector<Mismatch> locate_mismatches(const PlantModel& plant, const FrfData& model, const PlantFrfEvaluator& eval,
                                        const std::vector<Mode>& model_modes, double window_threshold = 4.0);

// The JSON document of cli.md (plus extra keys: entries, modes, noise floor).
nlohmann::json explain_to_json(const ExplainResult& r);

// Measured vs model vs improved model (|H| and phase) of the four entries
// with the largest mismatch, mismatch bands shaded: an SVG document.
std::string explain_svg(const ExplainResult& r, const FrfData& measured);

}  // namespace ambdiag
