#include "beam_element.h"

#include <cmath>
#include <numbers>

namespace ambdiag::detail {

BeamSection beam_section(const ShaftElement& e, const Material& m) {
  BeamSection s;
  const double ro = e.od_m / 2.0, ri = e.id_m / 2.0;
  s.area_m2 = std::numbers::pi * (ro * ro - ri * ri);
  s.i_m4 = std::numbers::pi / 4.0 * (std::pow(ro, 4) - std::pow(ri, 4));
  const double nu = m.e_pa / (2.0 * m.g_pa) - 1.0;
  const double r = e.id_m / e.od_m;
  const double r2 = r * r;
  const double a = (1.0 + r2) * (1.0 + r2);
  s.kappa = 6.0 * (1.0 + nu) * a / ((7.0 + 6.0 * nu) * a + (20.0 + 12.0 * nu) * r2);
  s.phi = 12.0 * m.e_pa * s.i_m4 / (s.kappa * m.g_pa * s.area_m2 * e.length_m * e.length_m);
  return s;
}

Matrix4 beam_stiffness(const ShaftElement& e, const Material& m) {
  const BeamSection s = beam_section(e, m);
  const double L = e.length_m, p = s.phi;
  const double f = m.e_pa * s.i_m4 / ((1.0 + p) * L * L * L);
  Matrix4 k;
  k << 12, 6 * L, -12, 6 * L,                          //
      6 * L, (4 + p) * L * L, -6 * L, (2 - p) * L * L,  //
      -12, -6 * L, 12, -6 * L,                          //
      6 * L, (2 - p) * L * L, -6 * L, (4 + p) * L * L;
  return f * k;
}

Matrix4 beam_translational_mass(const ShaftElement& e, const Material& m) {
  const BeamSection s = beam_section(e, m);
  const double L = e.length_m, p = s.phi, p2 = p * p;
  const double mu = m.rho_kg_per_m3 * s.area_m2 + e.added_mass_kg_per_m;
  const double m1 = 13.0 / 35 + 7.0 / 10 * p + p2 / 3;
  const double m2 = 11.0 / 210 + 11.0 / 120 * p + p2 / 24;
  const double m3 = 9.0 / 70 + 3.0 / 10 * p + p2 / 6;
  const double m4 = 13.0 / 420 + 3.0 / 40 * p + p2 / 24;
  const double m5 = 1.0 / 105 + p / 60 + p2 / 120;
  const double m6 = 1.0 / 140 + p / 60 + p2 / 120;
  Matrix4 k;
  k << m1, m2 * L, m3, -m4 * L,              //
      m2 * L, m5 * L * L, m4 * L, -m6 * L * L,  //
      m3, m4 * L, m1, -m2 * L,                  //
      -m4 * L, -m6 * L * L, -m2 * L, m5 * L * L;
  return mu * L / ((1 + p) * (1 + p)) * k;
}

Matrix4 beam_rotary_mass(const ShaftElement& e, const Material& m) {
  const BeamSection s = beam_section(e, m);
  const double L = e.length_m, p = s.phi, p2 = p * p;
  const double m7 = 6.0 / 5;
  const double m8 = 1.0 / 10 - p / 2;
  const double m9 = 2.0 / 15 + p / 6 + p2 / 3;
  const double m10 = -1.0 / 30 - p / 6 + p2 / 6;
  Matrix4 k;
  k << m7, m8 * L, -m7, m8 * L,                //
      m8 * L, m9 * L * L, -m8 * L, m10 * L * L,  //
      -m7, -m8 * L, m7, -m8 * L,                 //
      m8 * L, m10 * L * L, -m8 * L, m9 * L * L;
  return m.rho_kg_per_m3 * s.i_m4 / (L * (1 + p) * (1 + p)) * k;
}

}  // namespace ambdiag::detail
