// Timoshenko beam element matrices for one bending plane, in the standard
// DOF order (w1, theta1, w2, theta2) with theta = dw/dz.
//
// Stiffness and consistent translational and rotary mass after
// Przemieniecki (1968) and Friswell et al., Dynamics of Rotating Machines
// (2010), section 5.4.4, with the shear parameter
//   Phi = 12 E I / (kappa G A L^2)
// and Cowper's (1966) shear coefficient of the hollow circle.
#pragma once

#include <Eigen/Core>

#include "ambdiag/core/plant_model.h"

namespace ambdiag::detail {

using Matrix4 = Eigen::Matrix4d;

struct BeamSection {
  double area_m2 = 0.0;
  double i_m4 = 0.0;      // diametral second moment of area
  double kappa = 0.0;     // Cowper's shear coefficient
  double phi = 0.0;       // shear parameter of the element
};

BeamSection beam_section(const ShaftElement& e, const Material& m);

// Bending stiffness, N/m (and N m/rad, N per rad, as the DOFs require).
Matrix4 beam_stiffness(const ShaftElement& e, const Material& m);
// Translational mass, from rho A plus the non-structural added mass per length.
Matrix4 beam_translational_mass(const ShaftElement& e, const Material& m);
// Rotary inertia of the cross-sections per plane: integral of rho I N'^T N'.
// The polar counterpart (gyroscopic matrix) is twice this for a circle.
Matrix4 beam_rotary_mass(const ShaftElement& e, const Material& m);

}  // namespace ambdiag::detail
