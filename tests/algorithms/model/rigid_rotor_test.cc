// A short, thick (effectively rigid) rotor with a central disk on two equal
// isotropic springs, whose lateral modes are known in closed form:
//   cylindrical (bounce):  w^2 = 2 k / m, independent of speed;
//   conical (rocking):     Id w^2 -/+ Ip Omega w - k_theta = 0, k_theta = 2 k a^2,
// forward (minus sign) rising and backward (plus) falling with speed. m, Id
// and Ip include the shaft's own mass and inertia, from the same geometry.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <vector>

#include "ambdiag/algorithms/model/modal_analysis.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kRho = 7810.0;
constexpr double kElementM = 0.2, kOdM = 0.2;  // two elements: 0.4 m long, 0.2 m thick
constexpr double kSpringNPerM = 1e6;
constexpr double kDiskKg = 20.0, kDiskIdKgM2 = 0.5, kDiskIpKgM2 = 1.0;

PlantModel rigid_rotor() {
  PlantModel p;
  p.name = "rigid rotor";
  p.materials["steel"] = Material{2.11e11, 8.12e10, kRho};
  p.shaft = {ShaftElement{kElementM, kOdM, 0.0, "steel", 0.0},
             ShaftElement{kElementM, kOdM, 0.0, "steel", 0.0}};
  p.disks = {Disk{"disk", 1, kDiskKg, kDiskIdKgM2, kDiskIpKgM2}};
  for (int node : {0, 2}) {
    Link l;
    l.name = "spring" + std::to_string(node);
    l.node = node;
    l.kind = "bearing";
    l.coef[static_cast<int>(LinkCoef::kxx)] = kSpringNPerM;
    l.coef[static_cast<int>(LinkCoef::kyy)] = kSpringNPerM;
    p.links.push_back(l);
  }
  return p;
}

// Rigid-body properties about the centre (the disk): a solid cylinder of
// length L and radius r has Id = m (r^2/4 + L^2/12) and Ip = m r^2 / 2.
struct RigidBody {
  double m_kg, id_kg_m2, ip_kg_m2, k_theta_nm_per_rad;
};
RigidBody rigid_body() {
  const double length_m = 2 * kElementM, r = kOdM / 2;
  const double shaft_kg = kRho * kPi * r * r * length_m;
  return {shaft_kg + kDiskKg, kDiskIdKgM2 + shaft_kg * (r * r / 4 + length_m * length_m / 12),
          kDiskIpKgM2 + shaft_kg * r * r / 2, 2 * kSpringNPerM * kElementM * kElementM};
}

// Conical frequencies (Hz) at spin omega: forward and backward roots.
std::pair<double, double> conical_hz(double speed_rpm) {
  const RigidBody b = rigid_body();
  const double omega = speed_rpm * 2 * kPi / 60, g = b.ip_kg_m2 * omega;
  const double root = std::sqrt(g * g + 4 * b.id_kg_m2 * b.k_theta_nm_per_rad);
  return {(g + root) / (2 * b.id_kg_m2) / (2 * kPi), (-g + root) / (2 * b.id_kg_m2) / (2 * kPi)};
}

struct RigidModes {
  std::vector<double> cylindrical_hz;
  double forward_conical_hz = 0.0, backward_conical_hz = 0.0;
};

// The four lowest modes, split by shape: the two bearing nodes move in
// phase (cylindrical) or in anti-phase (conical).
RigidModes rigid_modes(double speed_rpm) {
  RigidModes out;
  const ModalResult r = modal_analysis(rigid_rotor(), speed_rpm);
  int taken = 0;
  for (const auto& m : r.modes) {
    if (m.kind != "rotor" || m.f_hz == 0.0 || taken == 4) continue;
    ++taken;
    const std::complex<double> x0 = m.shape(0), y0 = m.shape(1), x2 = m.shape(8), y2 = m.shape(9);
    const double in_phase = std::norm(x0 + x2) + std::norm(y0 + y2),
                 anti = std::norm(x0 - x2) + std::norm(y0 - y2);
    if (in_phase > anti) {
      out.cylindrical_hz.push_back(m.f_hz);
    } else if (speed_rpm == 0.0) {  // standstill: both conical modes are one repeated pair
      (out.forward_conical_hz == 0.0 ? out.forward_conical_hz : out.backward_conical_hz) = m.f_hz;
    } else {
      (m.whirl == Whirl::forward ? out.forward_conical_hz : out.backward_conical_hz) = m.f_hz;
    }
  }
  return out;
}

TEST(RigidRotor, MatchesClosedFormCylindricalAndConicalModesWithinHalfAPercent) {
  const RigidBody b = rigid_body();
  const double cylindrical_hz = std::sqrt(2 * kSpringNPerM / b.m_kg) / (2 * kPi);
  double worst = 0.0;
  for (double rpm : {0.0, 3000.0, 10000.0}) {
    const RigidModes got = rigid_modes(rpm);
    ASSERT_EQ(got.cylindrical_hz.size(), 2u) << rpm;
    for (double f : got.cylindrical_hz) {
      EXPECT_NEAR(f, cylindrical_hz, 0.005 * cylindrical_hz) << rpm << " rpm";
      worst = std::max(worst, std::abs(f - cylindrical_hz) / cylindrical_hz);
    }
    const auto [fwd_hz, bwd_hz] = conical_hz(rpm);
    EXPECT_NEAR(got.forward_conical_hz, fwd_hz, 0.005 * fwd_hz) << rpm << " rpm";
    EXPECT_NEAR(got.backward_conical_hz, bwd_hz, 0.005 * bwd_hz) << rpm << " rpm";
    RecordProperty("conical_rel_errors_" + std::to_string(static_cast<int>(rpm)),
                   std::to_string((got.forward_conical_hz - fwd_hz) / fwd_hz) + " " +
                       std::to_string((got.backward_conical_hz - bwd_hz) / bwd_hz));
    worst = std::max({worst, std::abs(got.forward_conical_hz - fwd_hz) / fwd_hz,
                      std::abs(got.backward_conical_hz - bwd_hz) / bwd_hz});
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
}

TEST(RigidRotor, ForwardConicalRisesAndBackwardFallsWithSpeed) {
  const RigidModes slow = rigid_modes(0.0), mid = rigid_modes(3000.0), fast = rigid_modes(10000.0);
  EXPECT_LT(slow.forward_conical_hz, mid.forward_conical_hz);
  EXPECT_LT(mid.forward_conical_hz, fast.forward_conical_hz);
  EXPECT_GT(slow.backward_conical_hz, mid.backward_conical_hz);
  EXPECT_GT(mid.backward_conical_hz, fast.backward_conical_hz);
  // Gyroscopic coupling leaves the symmetric bounce mode alone.
  EXPECT_NEAR(fast.cylindrical_hz.at(0), slow.cylindrical_hz.at(0), 1e-6 * slow.cylindrical_hz.at(0));
  // Product of the conical roots is k_theta / Id at every speed.
  const RigidBody b = rigid_body();
  const double w2 = b.k_theta_nm_per_rad / b.id_kg_m2 / (4 * kPi * kPi);
  EXPECT_NEAR(fast.forward_conical_hz * fast.backward_conical_hz, w2, 0.005 * w2);
}

}  // namespace
}  // namespace ambdiag
