// Modal features of identified modes and their labelling against a plant
// model (the paper's Table 3: identified vs model, with modes the model
// lacks and model modes that were not detected).
//
// Which sensors and actuators see a mode comes from its residue pattern: the
// share of the mode's resonance peak (|r| / |Re p|, in units of sigma) in each
// FRF entry. Its direction is axial when axial entries (sensor and actuator
// both axial) carry most of it. Its whirl comes from the residues of the x
// and y sensors of one plane over the same actuator: a forward circular
// mode has Y = -j X, so Im(conj(r_x) r_y) < 0 for forward whirl.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "ambdiag/algorithms/identification/rational_fit.h"
#include "ambdiag/algorithms/model/modal_analysis.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag {

struct ModeDescription {
  IdentifiedMode mode;
  std::string direction = "radial";  // "radial" or "axial"
  Whirl whirl = Whirl::none;
  std::vector<std::string> outputs;  // sensors that see it (share >= 5 % of the strongest)
  std::vector<std::string> inputs;   // actuators that excite it
  std::string label;                 // from the model, when paired
  int model_index = -1;              // into the model's mode list, when paired
};

// Axis of a measurement point: from the plant when given, else from the
// name's last letter (x, y, z; z means axial).
ModeDescription describe_mode(const IdentifiedMode& mode, const RationalFitResult& fit, const FrfData& frf,
                              const PlantModel* plant);

struct ModePairing {
  std::vector<ModeDescription> identified;    // with label/model_index where paired
  std::vector<int> unmatched_model;           // indices into the model modes
  std::vector<int> unmatched_identified;      // indices into `identified`
};

// Pairs identified modes with model modes of the same direction (and whirl,
// when both are known) by relative frequency distance, closest pairs first,
// within `max_rel_distance`. Model modes outside [f_min, f_max] are ignored.
ModePairing pair_with_model(std::vector<ModeDescription> identified, const std::vector<Mode>& model_modes,
                            double f_min_hz, double f_max_hz, double max_rel_distance = 0.15);

}  // namespace ambdiag
