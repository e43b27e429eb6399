// The linearised i-s law of a differential magnet pair from its load
// capacity, bias current and air gap (docs/simulation.md).
#include <cmath>
#include <numbers>
#include <string>

#include "ambdiag/algorithms/simulation/amb_loop.h"
#include "ambdiag/core/error.h"

namespace ambdiag {

namespace {

constexpr double kMu0 = 4e-7 * std::numbers::pi;  // H/m

void require_positive(double v, const char* name) {
  if (!std::isfinite(v) || v <= 0.0) throw InputError(std::string("AMB data: ") + name + " must be > 0");
}

}  // namespace

AmbLinearisation linearise_amb(const AmbMagnetData& m) {
  require_positive(m.air_gap_m, "air_gap_m");
  require_positive(m.bias_current_a, "bias_current_a");
  require_positive(m.max_force_n, "max_force_n");
  require_positive(m.pole_area_m2, "pole_area_m2");
  require_positive(m.turns_per_pole_pair, "turns_per_pole_pair");
  if (!std::isfinite(m.pole_angle_rad) || m.pole_angle_rad < 0.0 || m.pole_angle_rad >= std::numbers::pi / 2)
    throw InputError("AMB data: pole_angle_rad must be in [0, pi/2)");
  // One magnet of the pair: F = k (i / s)^2. The pair, biased with i0 and
  // driven differentially (i0 + i, i0 - i; gaps s0 - x, s0 + x):
  //   f = k [(i0 + i)^2 / (s0 - x)^2 - (i0 - i)^2 / (s0 + x)^2]
  //   k_i = 4 k i0 / s0^2 = 4 F0 / i0,  k_s = 4 k i0^2 / s0^3 = 4 F0 / s0,
  // F0 = k i0^2 / s0^2 the pull of one magnet at bias. The load capacity is
  // reached with one magnet at twice the bias flux and the other off:
  // f_max = 4 F0. Hence k_i = f_max / i0 and k_s = f_max / s0.
  AmbLinearisation l;
  l.k_i_n_per_a = m.max_force_n / m.bias_current_a;
  l.k_s_n_per_m = m.max_force_n / m.air_gap_m;
  // Flux at f_max: a magnet has two poles of area A at angle alpha,
  // f = 2 B^2 A cos(alpha) / (2 mu0).
  l.max_flux_t = std::sqrt(m.max_force_n * kMu0 / (m.pole_area_m2 * std::cos(m.pole_angle_rad)));
  l.bias_flux_t = l.max_flux_t / 2.0;
  // Ideal magnetic circuit (two air gaps, no iron, no leakage).
  l.coil_bias_flux_t = kMu0 * m.turns_per_pole_pair * m.bias_current_a / (2.0 * m.air_gap_m);
  return l;
}

AmbMagnetData nordmann_aenis_radial_amb() {
  AmbMagnetData m;
  m.air_gap_m = 0.3e-3;
  m.bias_current_a = 4.0;
  m.max_force_n = 750.0;
  m.pole_area_m2 = 864e-6;
  m.turns_per_pole_pair = 306;
  m.pole_angle_rad = std::numbers::pi / 8;  // 8 poles, a pole pair per axis half
  return m;
}

AmbMagnetData nordmann_aenis_axial_amb() {
  AmbMagnetData m;
  m.air_gap_m = 1.2e-3;
  m.bias_current_a = 3.6;
  m.max_force_n = 2200.0;
  m.pole_area_m2 = 2720e-6;
  m.turns_per_pole_pair = 286;
  m.pole_angle_rad = 0.0;
  return m;
}

}  // namespace ambdiag
