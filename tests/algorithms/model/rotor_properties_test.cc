// Physical properties the rotor model must have, on the reference pump:
// gyroscopic stiffening of forward whirl, the destabilising effect of seal
// cross-coupling, refusal of unphysical models, free-free rotors.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <nlohmann/json.hpp>
#include <numbers>
#include <vector>

#include "ambdiag/algorithms/model/modal_analysis.h"
#include "ambdiag/algorithms/model/rotor_system.h"
#include "ambdiag/core/error.h"
#include "ambdiag/core/plant_model.h"
#include "test_support.h"

namespace ambdiag {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

PlantModel pump() { return read_plant_file(testing::data_file("reference_pump/plant.json")); }

double mac(const Eigen::VectorXcd& a, const Eigen::VectorXcd& b) {
  return std::norm(a.dot(b)) / (a.squaredNorm() * b.squaredNorm());
}

// The rotor mode at `rpm` whose shape is closest (MAC) to `shape`.
Mode best_match(const PlantModel& p, double rpm, const Eigen::VectorXcd& shape, double* best_mac = nullptr) {
  const ModalResult r = modal_analysis(p, rpm);
  const Mode* best = nullptr;
  double best_m = -1;
  for (const auto& m : r.modes) {
    if (m.kind != "rotor" || m.f_hz == 0.0 || m.overdamped) continue;
    const double v = mac(m.shape, shape);
    if (v > best_m) {
      best_m = v;
      best = &m;
    }
  }
  if (best_mac) *best_mac = best_m;
  return *best;
}

// Forward-whirl rotor modes in the bending range (the rigid-body modes are
// at 22 and 49 Hz, the bending modes at 186, 606 and 900 Hz).
std::vector<Mode> forward_bending(const ModalResult& r) {
  std::vector<Mode> out;
  for (const auto& m : r.modes)
    if (m.kind == "rotor" && !m.overdamped && m.whirl == Whirl::forward && m.f_hz > 100 && m.f_hz < 1000)
      out.push_back(m);
  return out;
}

TEST(RotorProperties, ForwardWhirlBendingFrequenciesRiseWithSpeed) {
  const PlantModel p = pump();
  const std::vector<Mode> top = forward_bending(modal_analysis(p, 2950));
  ASSERT_EQ(top.size(), 3u);
  for (const auto& m : top) {
    double mac_mid = 0, mac_low = 0;
    const Mode mid = best_match(p, 1500, m.shape, &mac_mid);
    // At standstill forward and backward are one repeated pair: the best
    // match is one vector of that eigenspace (MAC >= 0.5), its frequency is the pair's.
    const Mode low = best_match(p, 0, m.shape, &mac_low);
    EXPECT_GT(mac_mid, 0.9);
    EXPECT_GT(mac_low, 0.45);
    EXPECT_EQ(mid.whirl, Whirl::forward);
    EXPECT_LT(low.f_hz, mid.f_hz) << m.f_hz << " Hz mode";
    EXPECT_LT(mid.f_hz, m.f_hz) << m.f_hz << " Hz mode";
    RecordProperty("forward_" + std::to_string(static_cast<int>(m.f_hz)) + "_hz",
                   std::to_string(low.f_hz) + " " + std::to_string(mid.f_hz) + " " + std::to_string(m.f_hz));
  }
}

// Adds kxy = -kyx = dk to a link, also in every table row that sets them
// (a table value replaces the top-level one).
void add_cross_coupling(Link& l, double dk_n_per_m) {
  const int xy = static_cast<int>(LinkCoef::kxy), yx = static_cast<int>(LinkCoef::kyx);
  l.coef[xy] += dk_n_per_m;
  l.coef[yx] -= dk_n_per_m;
  for (auto& row : l.table) {
    if (row.values[xy]) *row.values[xy] += dk_n_per_m;
    if (row.values[yx]) *row.values[yx] -= dk_n_per_m;
  }
}

TEST(RotorProperties, SealCrossCouplingDampsBackwardAndUndampsForwardWhirl) {
  const PlantModel base = pump();
  PlantModel coupled = base;
  bool found = false;
  for (auto& l : coupled.links) {
    if (l.name != "impeller_seal") continue;
    add_cross_coupling(l, 1e5);
    found = true;
  }
  ASSERT_TRUE(found);
  const ModalResult r = modal_analysis(base, 2950);
  // First bending pair.
  const Mode* fwd = nullptr;
  const Mode* bwd = nullptr;
  for (const auto& m : r.modes) {
    if (m.kind != "rotor" || m.overdamped || m.f_hz < 100) continue;
    if (!fwd && m.whirl == Whirl::forward) fwd = &m;
    if (!bwd && m.whirl == Whirl::backward) bwd = &m;
  }
  ASSERT_TRUE(fwd && bwd);
  double mac_f = 0, mac_b = 0;
  const Mode fwd2 = best_match(coupled, 2950, fwd->shape, &mac_f);
  const Mode bwd2 = best_match(coupled, 2950, bwd->shape, &mac_b);
  EXPECT_GT(mac_f, 0.9);
  EXPECT_GT(mac_b, 0.9);
  EXPECT_EQ(fwd2.whirl, Whirl::forward);
  EXPECT_EQ(bwd2.whirl, Whirl::backward);
  EXPECT_LT(fwd2.zeta, fwd->zeta);
  EXPECT_GT(bwd2.zeta, bwd->zeta);
  RecordProperty("zeta_forward", std::to_string(fwd->zeta) + " -> " + std::to_string(fwd2.zeta));
  RecordProperty("zeta_backward", std::to_string(bwd->zeta) + " -> " + std::to_string(bwd2.zeta));
}

TEST(RotorProperties, RefusesUnphysicalModels) {
  const nlohmann::json doc = plant_to_json(pump());
  auto refused = [&](auto edit) {
    nlohmann::json d = doc;
    edit(d);
    EXPECT_THROW(plant_from_json(d), InputError);
  };
  refused([](nlohmann::json& d) { d["disks"][0]["m"] = -2.0; });
  refused([](nlohmann::json& d) { d["shaft"][3]["L"] = 0.0; });
  refused([](nlohmann::json& d) { d["links"][0]["node"] = 99; });
  refused([](nlohmann::json& d) { d["links"][0]["mxx"] = -1.0; });

  // Built in code, past the reader: the solver path refuses them too.
  PlantModel p = pump();
  p.disks[0].m_kg = -2.0;
  EXPECT_THROW(modal_analysis(p, 0), InputError);
  p = pump();
  p.shaft[3].length_m = 0.0;
  EXPECT_THROW(modal_analysis(p, 0), InputError);
  p = pump();
  p.links[0].node = 99;
  EXPECT_THROW(modal_analysis(p, 0), InputError);
  // A large negative link mass makes M indefinite.
  p = pump();
  p.links[0].coef[static_cast<int>(LinkCoef::mxx)] = -1000.0;
  EXPECT_THROW(modal_analysis(p, 0), InputError);
}

// Rigid-body inertia of the FE rotor about its centre of mass: elements
// carry rho A + added mass (translation) and rho I (rotary, polar 2 rho I).
std::pair<double, double> rigid_id_ip(const PlantModel& p) {
  const std::vector<double> z = p.node_positions_m();
  double m = 0, mz = 0;
  for (size_t i = 0; i < p.shaft.size(); ++i) {
    const auto& e = p.shaft[i];
    const double area = std::numbers::pi / 4 * (e.od_m * e.od_m - e.id_m * e.id_m);
    const double me = (p.materials.at(e.material).rho_kg_per_m3 * area + e.added_mass_kg_per_m) * e.length_m;
    m += me;
    mz += me * (z[i] + e.length_m / 2);
  }
  for (const auto& d : p.disks) {
    m += d.m_kg;
    mz += d.m_kg * z[static_cast<size_t>(d.node)];
  }
  const double zc = mz / m;
  double id = 0, ip = 0;
  for (size_t i = 0; i < p.shaft.size(); ++i) {
    const auto& e = p.shaft[i];
    const double rho = p.materials.at(e.material).rho_kg_per_m3;
    const double area = std::numbers::pi / 4 * (e.od_m * e.od_m - e.id_m * e.id_m);
    const double i_m4 = std::numbers::pi / 64 * (std::pow(e.od_m, 4) - std::pow(e.id_m, 4));
    const double me = (rho * area + e.added_mass_kg_per_m) * e.length_m, dz = z[i] + e.length_m / 2 - zc;
    id += me * (dz * dz + e.length_m * e.length_m / 12) + rho * i_m4 * e.length_m;
    ip += 2 * rho * i_m4 * e.length_m;
  }
  for (const auto& d : p.disks) {
    const double dz = z[static_cast<size_t>(d.node)] - zc;
    id += d.id_kg_m2 + d.m_kg * dz * dz;
    ip += d.ip_kg_m2;
  }
  return {id, ip};
}

TEST(RotorProperties, FreeFreeRotorWorksAtStandstillAndAtSpeed) {
  PlantModel p = pump();
  p.links.clear();
  p.housings.clear();
  // Standstill: four rigid-body modes at f = 0, and the elastic modes are the
  // free-free plane modes with exactly the modal structural damping.
  const ModalResult still = modal_analysis(p, 0);
  const PlaneModes plane = free_free_plane_modes(p, 5);
  int zeros = 0;
  std::vector<const Mode*> elastic;
  for (const auto& m : still.modes) {
    if (m.kind != "rotor") continue;
    if (m.f_hz == 0.0) {
      ++zeros;
    } else if (elastic.empty() || m.f_hz > elastic.back()->f_hz * (1 + 1e-4)) {
      elastic.push_back(&m);
    }
  }
  EXPECT_EQ(zeros, 4);
  ASSERT_GE(elastic.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    const double want_hz = plane.omega_rad_per_s(2 + i) / kTwoPi;
    EXPECT_NEAR(elastic[static_cast<size_t>(i)]->f_hz, want_hz, 1e-6 * want_hz);
    EXPECT_NEAR(elastic[static_cast<size_t>(i)]->zeta, p.structural_damping.zeta, 1e-6);
  }
  // At speed the free tilt becomes a forward nutation at w = Ip Omega / Id
  // (rigid-body estimate; shaft flexibility lowers it slightly).
  const double rpm = 2950, omega = rpm * kTwoPi / 60;
  const ModalResult spin = modal_analysis(p, rpm);
  const auto [id, ip] = rigid_id_ip(p);
  const double nutation_hz = ip * omega / id / kTwoPi;
  const Mode* nut = nullptr;
  for (const auto& m : spin.modes) {
    ASSERT_TRUE(std::isfinite(m.f_hz) && std::isfinite(m.zeta));
    if (m.kind == "rotor" && m.f_hz > 0 && m.whirl == Whirl::forward && (!nut || m.f_hz < nut->f_hz))
      nut = &m;
  }
  ASSERT_NE(nut, nullptr);
  EXPECT_NEAR(nut->f_hz, nutation_hz, 0.01 * nutation_hz);
  EXPECT_LT(nut->f_hz, elastic[0]->f_hz);
  RecordProperty("nutation_hz", std::to_string(nut->f_hz) + " rigid estimate " + std::to_string(nutation_hz));
}

}  // namespace
}  // namespace ambdiag
