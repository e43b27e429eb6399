// Modal analysis of a plant model at one speed.
//
// Lateral rotor modes are the eigenvalues lambda of the first-order form
//   [0 I; -M^-1 K  -M^-1 (C + Omega G + C_s)],
// reported as f_hz = |lambda| / 2 pi, zeta = -Re(lambda) / |lambda|, one
// mode per complex-conjugate pair (Im lambda > 0); real eigenvalues are
// overdamped modes. Whirl from the mode shape: with complex amplitudes X, Y
// of a node, the forward circular part is |X + jY| / 2 and the backward
// part |X - jY| / 2; fwd_fraction sums their squares over the nodes.
// Housing resonances (in parallel) and the decoupled axial model add
// their modes in closed form.
#pragma once

#include <complex>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ambdiag/core/plant_model.h"

namespace ambdiag {

enum class Whirl { forward, backward, none };
std::string to_string(Whirl w);

struct Mode {
  double f_hz = 0.0;       // undamped natural frequency |lambda| / 2 pi
  double zeta = 0.0;       // damping ratio -Re(lambda) / |lambda|
  std::complex<double> eigenvalue;  // rad/s
  std::string direction;   // "radial" or "axial"
  std::string kind;        // "rotor", "housing", "axial", "axial_housing"
  Whirl whirl = Whirl::none;
  double fwd_fraction = 0.0;
  bool overdamped = false;  // real eigenvalue
  std::string label;        // e.g. "housing_A", "axial rigid body"
  Eigen::VectorXcd shape;   // lateral rotor modes: full DOF shape (x, y, tx, ty per node), max |x|,|y| = 1
  // Log decrement 2 pi zeta / sqrt(1 - zeta^2) (infinite when overdamped).
  double log_decrement() const;
};

struct ModalOptions {
  bool overdamped = true;  // also report real (overdamped) rotor eigenvalues
  bool shapes = true;      // keep mode shapes
};

struct ModalResult {
  double speed_rpm = 0.0;
  std::vector<Mode> modes;  // ascending f_hz
};

ModalResult modal_analysis(const PlantModel& plant, double speed_rpm, const ModalOptions& options = {});

}  // namespace ambdiag
