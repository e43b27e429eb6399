// A pump in active magnetic bearings, simulated in closed loop in discrete
// time (docs/simulation.md derives every choice).
//
// Mechanics: the plant model (rotor_system.h) with its housings and axial
// model, as a continuous state space driven by the bearing forces f and an
// external (unbalance) force. Bearings: the linearised i-s law of Nordmann &
// Aenis (2004), eq. 4, per axis
//
//   f = k_i i + k_s s                                                   (1)
//
// with s the air gap change (rotor relative to housing at the actuator
// node) and i the control current; k_s > 0 is the negative stiffness.
// Controller: per actuator a digital PD with a first-order derivative
// filter (optional integral) on the sensor of the same plane and
// direction, running at `controller_rate_hz`, output held (zero-order hold)
// and applied one sample after the measurement (computation delay). The
// excitation reference r (N) is added to the current as r / k_i.
//
// Discretisation is exact for the held inputs: Phi = e^{A h} and
// Gamma = int_0^h e^{A s} ds B from one matrix exponential of [[A B][0 0]] h.
//
// Recorded channels (every `decimation` controller samples): the bearing
// force by the i-s method, k_i i_meas + k_s s_meas (nominal k_i, k_s), and
// the sensor displacements, both through the same 4th-order Butterworth
// anti-alias filter (continuous, part of the state), plus white measurement
// noise. The same filter on inputs and outputs leaves x/f unchanged, and it
// removes the images of the held current around multiples of the
// controller rate, so the FRF estimated from a run is the model's FRF up to
// noise (the estimator uses the noise-free references as instruments).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ambdiag/core/plant_model.h"

namespace ambdiag {

// One axis of a differential electromagnet pair (8-pole radial bearing, or
// an axial bearing) as given in Table 1 of the paper.
struct AmbMagnetData {
  double air_gap_m = 0.0;          // nominal air gap s0
  double bias_current_a = 0.0;     // i0
  double max_force_n = 0.0;        // load capacity per axis
  double pole_area_m2 = 0.0;       // A per pole
  double turns_per_pole_pair = 0.0;
  double pole_angle_rad = 0.0;     // angle of a pole to the axis (pi/8 radial 8-pole, 0 axial)
};

// k_i = f_max / i0 and k_s = f_max / s0 (f_max = 4 F0 at twice the bias flux;
// docs/simulation.md), with the fluxes that go with them.
struct AmbLinearisation {
  double k_i_n_per_a = 0.0;
  double k_s_n_per_m = 0.0;
  double bias_flux_t = 0.0;       // B0 = B_max / 2
  double max_flux_t = 0.0;        // flux at f_max over the pole area
  double coil_bias_flux_t = 0.0;  // mu0 N i0 / (2 s0): what the coil data would give without iron and leakage
};
// Throws InputError if a value is not finite and > 0 (pole angle >= 0).
AmbLinearisation linearise_amb(const AmbMagnetData& m);
// Table 1 of Nordmann & Aenis (2004).
AmbMagnetData nordmann_aenis_radial_amb();
AmbMagnetData nordmann_aenis_axial_amb();

struct AmbLoopOptions {
  double controller_rate_hz = 8192.0;
  int decimation = 4;  // controller samples per recorded sample
  AmbMagnetData radial = nordmann_aenis_radial_amb();
  AmbMagnetData axial = nordmann_aenis_axial_amb();
  // Bearing stiffness and damping the PD controller gives at the operating
  // point: k = k_i kp - k_s, d = k_i kd. 0: defaults (k = k_s, d below;
  // a negative k is allowed, it is what a too small kp gives),
  // unless a link of kind "bearing" sits on the actuator's node (its direct
  // coefficients are then the targets, and the link leaves the mechanics).
  double radial_stiffness_n_per_m = 0.0;
  double radial_damping_ns_per_m = 0.0;  // 0: 2 zeta sqrt(k m_share), zeta 0.3
  double axial_stiffness_n_per_m = 0.0;
  double axial_damping_ns_per_m = 0.0;
  double integral_corner_hz = 0.0;         // ki = kp 2 pi f (0: PD only)
  double derivative_corner_hz = 0.0;       // 0: controller_rate / 8
  double anti_alias_hz = 0.0;              // 0: 0.45 x recorded sample rate
  double displacement_noise_m = 0.05e-6;   // rms, sensor (loop and record)
  double current_noise_a = 2e-3;           // rms, current measurement
  std::vector<double> sensor_gain;         // per sensor (empty: 1); faults
  std::vector<double> actuator_gain;       // per actuator: true force / i-s law
  // Unbalance u (kg m) at a node: force u Omega^2 rotating with the shaft.
  double unbalance_kg_m = 0.0;
  int unbalance_node = -1;
  uint64_t seed = 1;
};

// What the loop looks like after set-up.
struct AmbLoopReport {
  std::vector<double> k_i_n_per_a, k_s_n_per_m;         // per actuator
  std::vector<double> kp_a_per_m, kd_a_s_per_m, ki_a_per_m_s;
  std::vector<double> stiffness_n_per_m, damping_ns_per_m;  // targets
  double spectral_radius = 0.0;  // of the closed loop's discrete transition matrix
  int states = 0;                // continuous states (mechanics + filters)
};

class AmbLoop {
 public:
  // r(k, r_n): fills one reference per actuator (N) at controller step k,
  // counted from the start of the run() call (k / controller rate seconds).
  using Reference = std::function<void(int64_t k, std::span<double> r_n)>;

  // Throws InputError if an actuator has no sensor of its plane and
  // direction, a gain vector has the wrong size, or the controller does
  // not stabilise the plant (spectral radius >= 1, named in the message).
  AmbLoop(const PlantModel& plant, const AmbLoopOptions& opt);
  ~AmbLoop();
  AmbLoop(AmbLoop&&) noexcept;
  AmbLoop& operator=(AmbLoop&&) noexcept;

  const AmbLoopReport& report() const;
  double record_rate_hz() const;
  double controller_rate_hz() const;
  // Advances n recorded samples (n x decimation controller steps) from the
  // current state; fills references, forces (n_act x n) and displacements
  // (n_sens x n). The pump keeps its state from the previous call.
  void run(int64_t n, const Reference& ref, Eigen::MatrixXd& r_n, Eigen::MatrixXd& f_n, Eigen::MatrixXd& x_m);
  double time_s() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ambdiag
