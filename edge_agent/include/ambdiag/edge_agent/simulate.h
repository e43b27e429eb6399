// A simulated pump for `ambdiag-agent simulate`: the plant model in closed
// loop with its magnetic bearings (algorithms/amb_loop.h: i-s law with k_i,
// k_s from Table 1 of Nordmann & Aenis 2004, digital PD controller with
// one sample of delay, exact discretisation; docs/simulation.md).
//
// Identification runs inject the excitation as an added current r / k_i:
//  - multisine: one segment per actuator, all actuators at once with phase
//    pattern p (input j shifted by 2 pi p j / n_inputs, so the segments are
//    linearly independent), settle periods first;
//  - stepsine: one actuator and one frequency per segment, whole periods in
//    the measured part (run-recording.md).
// Channels: references (noise free), bearing forces by the i-s method and
// displacements with noise, and the speed, in the run-recording layout, so
// `ambdiag frf` estimates the plant's FRF from a run.
// Monitoring snapshots: a stretch without excitation; 1x and 2x bearing
// forces and the orbits of bearings A and B.
//
// Faults by name, NAME or NAME=VALUE (docs/simulation.md):
//   sensor_fault[=gain 0.8]     first sensor's gain (the controller sees it too)
//   actuator_fault[=gain 0.7]   first actuator's true force / the i-s law's
//   unbalance[=u kg m]          rotating force u Omega^2 at the impeller
//                               (default 10x G 2.5, the healthy residual)
//   dry_run[=fluid_factor 0], balance_piston_wear[=clearance_factor 2],
//   impeller_seal_wear[=2], rotor_crack[=EI_factor 0.5] (the shaft element
//   left of the impeller), shaft_nut_loosening[=joint_factor 0.5]:
//   the plant changes of algorithms/fault_models.h.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ambdiag/algorithms/amb_loop.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/run_recording.h"

namespace ambdiag::agent {

struct SimulationOptions {
  std::string pump_id;
  std::vector<std::string> faults;
  std::string excitation = "multisine";  // multisine | stepsine
  double sample_rate_hz = 2048.0;        // recorded; the controller runs at a multiple >= 8 kHz
  int64_t period_samples = 2048;         // multisine: 1 Hz lines
  double f_min_hz = 1.0;
  double f_max_hz = 1000.0;
  int settle_periods = 2;
  int meas_periods = 4;
  double force_rms_n = 20.0;             // multisine, per actuator
  int stepsine_steps = 30;               // per actuator, log-spaced f_min..f_max
  double stepsine_amplitude_n = 20.0;
  double stepsine_settle_s = 0.15;
  double stepsine_meas_s = 0.1;          // at least; whole periods
  double monitoring_s = 1.0;             // snapshot window
  double unbalance_grade_mm_per_s = 2.5; // healthy residual unbalance (ISO 21940 G); 0: none
  AmbLoopOptions loop;                   // rates and unbalance are set from the above
  uint64_t seed = 1;
};

// One monitoring snapshot (the IDL's MonitoringSnapshot; index order Ax, Ay,
// Bx, By; orbits of bearings A, B). Channels the model lacks stay 0.
struct Snapshot {
  double speed_rpm = 0;
  std::array<double, 4> force_1x_amp_n{}, force_1x_phase_rad{}, force_2x_amp_n{}, force_2x_phase_rad{};
  std::array<double, 2> orbit_major_m{}, orbit_minor_m{}, orbit_center_x_m{}, orbit_center_y_m{};
  double displacement_rms_m = 0;  // over the lateral sensors
};

class PumpSimulator {
 public:
  // Throws InputError for a bad model file, an unknown fault name or value,
  // or bad options.
  PumpSimulator(const std::string& model_path, SimulationOptions opt);
  PumpSimulator(PlantModel plant, SimulationOptions opt);
  ~PumpSimulator();
  // The next identification run (run_id "<pump>/sim-<n>-<UTC time>").
  RunRecording identification_run();
  Snapshot monitoring_snapshot();
  const PlantModel& plant() const { return plant_; }  // with the plant faults applied
  const AmbLoop& loop() const { return *loop_; }

 private:
  RunRecording new_run(const std::string& kind);
  void append(RunRecording& run, const Eigen::MatrixXd& r, const Eigen::MatrixXd& f, const Eigen::MatrixXd& x) const;
  RunRecording multisine_run();
  RunRecording stepsine_run();

  PlantModel plant_;
  SimulationOptions opt_;
  std::unique_ptr<AmbLoop> loop_;
  int runs_ = 0;
};

}  // namespace ambdiag::agent
