#include "ambdiag/algorithms/diagnosis/fault_models.h"

#include <algorithm>
#include <cctype>
#include <stdexcept>

namespace ambdiag {

namespace {

bool contains_ci(std::string s, std::string_view what) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s.find(what) != std::string::npos;
}

// Scales E and G of the listed elements through a private copy of each
// element's material, so other elements of the same material keep theirs.
void scale_bending_stiffness(PlantModel& p, const std::vector<int>& elements, double factor) {
  for (int e : elements) {
    ShaftElement& el = p.shaft.at(static_cast<size_t>(e));
    Material m = p.materials.at(el.material);
    m.e_pa *= factor;
    m.g_pa *= factor;
    std::string name = el.material + "#fault_element_" + std::to_string(e);
    p.materials[name] = m;
    el.material = name;
  }
}

}  // namespace

std::string to_string(FaultKind kind) {
  switch (kind) {
    case FaultKind::dry_run: return "dry_run";
    case FaultKind::balance_piston_wear: return "balance_piston_wear";
    case FaultKind::impeller_seal_wear: return "impeller_seal_wear";
    case FaultKind::rotor_crack: return "rotor_crack";
    case FaultKind::shaft_nut_loosening: return "shaft_nut_loosening";
    case FaultKind::sensor_fault: return "sensor_fault";
    case FaultKind::actuator_fault: return "actuator_fault";
  }
  return "unknown";
}

bool is_plant_fault(FaultKind kind) { return kind != FaultKind::sensor_fault && kind != FaultKind::actuator_fault; }

void scale_link(Link& link, double factor) {
  for (double& c : link.coef) c *= factor;
  for (auto& row : link.table)
    for (auto& v : row.values)
      if (v) *v *= factor;
}

std::vector<int> fluid_seal_links(const PlantModel& plant) {
  std::vector<int> out;
  for (size_t i = 0; i < plant.links.size(); ++i)
    if (plant.links[i].kind == "seal" || plant.links[i].kind == "balance_piston") out.push_back(static_cast<int>(i));
  return out;
}

std::vector<FaultHypothesis> fault_hypotheses(const PlantModel& plant) {
  std::vector<FaultHypothesis> out;
  std::vector<int> seals, pistons;
  for (size_t i = 0; i < plant.links.size(); ++i) {
    if (plant.links[i].kind == "seal") seals.push_back(static_cast<int>(i));
    if (plant.links[i].kind == "balance_piston") pistons.push_back(static_cast<int>(i));
  }
  if (!seals.empty() || !pistons.empty()) {
    FaultHypothesis h{FaultKind::dry_run, seals, {}, "", "fluid_factor", 1.0, 0.0, 1.2, 1};
    h.links.insert(h.links.end(), pistons.begin(), pistons.end());
    out.push_back(h);
  }
  // Clearance may shrink a little in the fit (noise), never below 0.8.
  for (int i : pistons)
    out.push_back({FaultKind::balance_piston_wear, {i}, {}, "", "clearance_factor", 1.0, 0.8, 8.0, static_cast<int>(pistons.size())});
  for (int i : seals)
    out.push_back({FaultKind::impeller_seal_wear, {i}, {}, "", "clearance_factor", 1.0, 0.8, 8.0, static_cast<int>(seals.size())});
  const int n_el = static_cast<int>(plant.shaft.size());
  for (int e = 0; e < n_el; ++e)
    out.push_back({FaultKind::rotor_crack, {}, {e}, "", "EI_factor", 1.0, 0.05, 1.2, n_el});
  for (const auto& d : plant.disks) {
    if (!contains_ci(d.name, "impeller")) continue;
    FaultHypothesis h{FaultKind::shaft_nut_loosening, {}, {}, "", "joint_factor", 1.0, 0.05, 1.2, 1};
    if (d.node - 1 >= 0) h.elements.push_back(d.node - 1);
    if (d.node < n_el) h.elements.push_back(d.node);
    out.push_back(h);
    break;
  }
  for (const auto& s : plant.sensors)
    out.push_back({FaultKind::sensor_fault, {}, {}, s.name, "gain", 1.0, 0.0, 3.0, static_cast<int>(plant.sensors.size())});
  for (const auto& a : plant.actuators)
    out.push_back({FaultKind::actuator_fault, {}, {}, a.name, "gain", 1.0, 0.0, 3.0, static_cast<int>(plant.actuators.size())});
  return out;
}

double link_coefficient_factor(const FaultHypothesis& h, double value) {
  switch (h.kind) {
    case FaultKind::dry_run: return value;
    case FaultKind::balance_piston_wear:
    case FaultKind::impeller_seal_wear: return 1.0 / value;
    default: return 1.0;
  }
}

PlantModel apply_fault(const PlantModel& plant, const FaultHypothesis& h, double value) {
  if (!is_plant_fault(h.kind)) throw std::logic_error("apply_fault: " + to_string(h.kind) + " is not a plant fault");
  PlantModel p = plant;
  const double f = link_coefficient_factor(h, value);
  for (int i : h.links) scale_link(p.links.at(static_cast<size_t>(i)), f);
  if (h.kind == FaultKind::rotor_crack || h.kind == FaultKind::shaft_nut_loosening) scale_bending_stiffness(p, h.elements, value);
  return p;
}

}  // namespace ambdiag
