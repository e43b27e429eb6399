// The plant model (`ambdiag.plant/1`, ../shared/specs/plant-model.md): one
// machine's rotor, links (bearings, seals, couplings), housings, axial model,
// sensors and actuators. SI units throughout; file frequencies in Hz, speeds
// in rpm.
#pragma once

#include <array>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json_fwd.hpp>

namespace ambdiag {

struct Material {
  double e_pa = 0.0;             // Young's modulus
  double g_pa = 0.0;             // shear modulus
  double rho_kg_per_m3 = 0.0;    // density
};

// Timoshenko beam element between node i and node i+1.
struct ShaftElement {
  double length_m = 0.0;
  double od_m = 0.0;
  double id_m = 0.0;
  std::string material;
  double added_mass_kg_per_m = 0.0;  // non-structural translational mass
};

struct Disk {
  std::string name;
  int node = 0;
  double m_kg = 0.0;
  double id_kg_m2 = 0.0;  // diametral moment of inertia
  double ip_kg_m2 = 0.0;  // polar moment of inertia
};

// The 12 link coefficients, in this order. K in N/m, C in N s/m, M in kg.
enum class LinkCoef { kxx, kxy, kyx, kyy, cxx, cxy, cyx, cyy, mxx, mxy, myx, myy };
inline constexpr int kLinkCoefCount = 12;
inline constexpr std::array<std::string_view, kLinkCoefCount> kLinkCoefNames = {
    "kxx", "kxy", "kyx", "kyy", "cxx", "cxy", "cyx", "cyy", "mxx", "mxy", "myx", "myy"};

using LinkCoefficients = std::array<double, kLinkCoefCount>;

struct LinkTableRow {
  double rpm = 0.0;
  std::array<std::optional<double>, kLinkCoefCount> values;  // absent: keep top-level value
};

// Rotor-to-ground link: f = -(K q + C dq/dt + M d2q/dt2) on the node's (x, y).
struct Link {
  std::string name;
  int node = 0;
  std::string kind;  // free text: seal, balance_piston, mechanical_seal, coupling, bearing
  LinkCoefficients coef{};
  std::vector<LinkTableRow> table;  // sorted by rpm, strictly increasing

  // Coefficients at a speed: linear in rpm between table rows, held at the
  // end rows outside the table; coefficients absent from the table keep the
  // top-level value.
  LinkCoefficients at_speed(double rpm) const;
  double get(LinkCoef c) const { return coef[static_cast<int>(c)]; }
};

// A housing resonance of a bearing plane, in parallel with the rotor.
struct Housing {
  std::string name;
  std::string plane;            // "A", "B", ...
  std::vector<std::string> dirs;  // subset of {"x", "y"}
  double f_hz = 0.0;
  double zeta = 0.0;
  double m_kg = 0.0;
};

struct AxialHousing {
  std::string name;
  double f_hz = 0.0;
  double zeta = 0.0;
  double m_kg = 0.0;
};

// Decoupled axial model: one mass-spring-damper plus housings in parallel.
struct AxialModel {
  std::optional<double> m_kg;  // null: computed from shaft, added mass and disks
  double k_n_per_m = 0.0;
  double c_ns_per_m = 0.0;
  std::vector<AxialHousing> housings;
};

struct StructuralDamping {
  enum class Kind { none, modal } kind = Kind::none;
  double zeta = 0.0;
};

struct Reduction {
  enum class Kind { none, modal } kind = Kind::none;
  int n_elastic_modes = 0;  // per plane
};

// A sensor or actuator. Lateral points sit on a node in direction x or y;
// axial points (dir z) act on the axial model and have no node.
struct MeasurementPoint {
  std::string name;
  std::string plane;  // "A", "B", or "Z" for axial
  std::optional<int> node;
  char dir = 'x';     // 'x', 'y' or 'z'
  bool is_axial() const { return dir == 'z'; }
};

struct PlantModel {
  std::string name;
  double speed_rpm = 0.0;
  std::map<std::string, Material> materials;
  std::vector<ShaftElement> shaft;
  std::vector<Disk> disks;
  std::vector<Link> links;
  std::vector<Housing> housings;
  std::optional<AxialModel> axial;
  StructuralDamping structural_damping;
  Reduction reduction;
  std::vector<MeasurementPoint> sensors;
  std::vector<MeasurementPoint> actuators;

  int node_count() const { return static_cast<int>(shaft.size()) + 1; }
  // Axial position of each node (cumulative element lengths), m.
  std::vector<double> node_positions_m() const;
  const MeasurementPoint* find_sensor(std::string_view name) const;
  const MeasurementPoint* find_actuator(std::string_view name) const;
  // Rotor mass from shaft (with added mass) and disks, kg.
  double rotor_mass_kg() const;
};

// Parses and validates a plant model document. Throws InputError naming the
// field (`shaft[3].od: must be > id`); never returns a half-loaded model.
PlantModel plant_from_json(const nlohmann::json& doc);
PlantModel read_plant_file(const std::string& path);
// Throws InputError if the parsed model breaks a rule of the spec (also used
// after programmatic edits, e.g. by fault models).
void validate_plant(const PlantModel& plant);

nlohmann::json plant_to_json(const PlantModel& plant);
// Writes atomically (temporary file, then rename).
void write_plant_file(const std::string& path, const PlantModel& plant);

}  // namespace ambdiag
