// Fault models: each fault is a parameterised change of the plant model (or,
// for sensor and actuator faults, of one row or column of the measured FRF
// matrix), with the physics documented in docs/diagnosis.md.
//
//  - dry_run: the fluid-film seals (links of kind `seal` and
//    `balance_piston`) lose their fluid; every coefficient K, C, M, direct
//    and cross-coupled, and its speed table scaled by fluid_factor in [0, 1]
//    (0: dry). Mechanical seals (contact seals) keep theirs.
//  - balance_piston_wear, impeller_seal_wear: the clearance Cr of one annular
//    seal grows by clearance_factor c >= 1. Childs' short-seal (bulk-flow)
//    coefficients K = mu3 mu0, C = mu3 mu1 T, M = mu3 mu2 T^2 at a fixed
//    pressure drop fall, to first order, in proportion to 1 / Cr (weaker
//    Lomakin effect through sigma = lambda L / Cr, shorter transit time T =
//    L / V); with unchanged inlet swirl the cross-coupled terms follow. So
//    every coefficient of the link is multiplied by 1 / c.
//  - rotor_crack: a local loss of bending stiffness at one shaft element,
//    E and G of that element multiplied by EI_factor (mass unchanged).
//  - shaft_nut_loosening: the impeller is clamped by its shaft nut; loose,
//    the hub no longer stiffens the shaft, so the elements on both sides of
//    the impeller's node lose bending stiffness by joint_factor.
//  - sensor_fault / actuator_fault: one channel's gain changes (drift,
//    calibration, dropout = gain 0): the FRF row of the sensor or column of
//    the actuator is multiplied by gain. These are additive faults of the
//    measurement chain, not of the machine.
// Unbalance and misalignment need monitoring runs (1x and 2x bearing
// forces), not FRFs; they have no model here.
#pragma once

#include <string>
#include <vector>

#include "ambdiag/core/plant_model.h"

namespace ambdiag {

enum class FaultKind { dry_run, balance_piston_wear, impeller_seal_wear, rotor_crack, shaft_nut_loosening, sensor_fault, actuator_fault };
std::string to_string(FaultKind kind);
// Plant faults change the model; the others scale FRF rows or columns.
bool is_plant_fault(FaultKind kind);

// One concrete hypothesis: a fault kind at one location, with one parameter.
struct FaultHypothesis {
  FaultKind kind = FaultKind::dry_run;
  std::vector<int> links;     // indices into PlantModel::links changed by it
  std::vector<int> elements;  // shaft elements changed by it
  std::string channel;        // sensor (row) or actuator (column) name
  std::string parameter;      // fluid_factor, clearance_factor, EI_factor, joint_factor, gain
  double nominal = 1.0;       // the healthy value
  double lower = 0.0, upper = 1.0;
  int alternatives = 1;       // locations of this kind searched (for the model-choice penalty)
};

// Every hypothesis the plant model supports: seals by link kind, one crack
// hypothesis per shaft element, the hub joint of the disk named `impeller`,
// one channel hypothesis per sensor and per actuator.
std::vector<FaultHypothesis> fault_hypotheses(const PlantModel& plant);

// The plant with the fault applied at parameter value `value` (a plant
// fault; throws std::logic_error for channel faults).
PlantModel apply_fault(const PlantModel& plant, const FaultHypothesis& h, double value);

// Factor on the link coefficients for seal faults (fluid_factor, or
// 1 / clearance_factor); 1 for other kinds.
double link_coefficient_factor(const FaultHypothesis& h, double value);

// Multiplies every coefficient of a link and of its speed table by `factor`.
void scale_link(Link& link, double factor);

// The links whose coefficients come from the fluid (kind `seal` or
// `balance_piston`), in link order: what a dry run removes and what
// temperature and flow make drift.
std::vector<int> fluid_seal_links(const PlantModel& plant);

}  // namespace ambdiag
