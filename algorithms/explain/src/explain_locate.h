// What locating needs besides the public locate_mismatches (explain.h).
#pragma once

#include <vector>

#include "ambdiag/algorithms/model/modal_analysis.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag::detail {

// The plant's modes up to fmax at a speed, with shapes (to name a band's mode).
std::vector<Mode> modes_in_band(const PlantModel& p, double rpm, double fmax);

}  // namespace ambdiag::detail
