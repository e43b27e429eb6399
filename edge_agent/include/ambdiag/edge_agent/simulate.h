// A simulated pump for `ambdiag-agent simulate` (first version).
//
// Identification runs are steady-state multisines synthesised from the
// plant model's FRF (algorithms/frf_synthesis.h): one segment per actuator,
// all actuators driven at once with phase pattern p (input j shifted by
// 2 pi p j / n_inputs, so the n segments are linearly independent), the
// displacement of each sensor x_i = sum_j H_ij(f) F_j(f) per line, with
// Gaussian measurement noise (1 % of each channel's rms) on forces and
// displacements.
//
// What it lacks: the closed loop. The paper's AMB law f = k_i i + k_s s with
// a digital controller (sampling, delay, the controller's own dynamics) is
// not simulated; forces equal the references (open loop), as if the
// bearing were an ideal force actuator. Faults change the measurement chain
// only: `sensor_fault` (gain 0.8 and offset on the first sensor),
// `actuator_fault` (gain 0.7 on the first actuator's force), `unbalance`
// (a 1x whirl on every lateral sensor); model faults (seal wear, crack, ...)
// are refused until the simulator perturbs the model.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/run_recording.h"

namespace ambdiag::agent {

struct SimulationOptions {
  std::string pump_id;
  std::vector<std::string> faults;
  double sample_rate_hz = 4096.0;
  int64_t period_samples = 4096;  // 1 Hz line spacing
  double f_min_hz = 5.0;
  double f_max_hz = 800.0;
  int settle_periods = 1;
  int meas_periods = 2;
  double force_rms_n = 20.0;      // per actuator
  double noise_fraction = 0.01;   // of each channel's rms
  uint64_t seed = 1;
  double duration_s = 0;          // unused by identification runs (set by periods)
};

class PumpSimulator {
 public:
  // Throws InputError for a bad model file or an unknown fault name.
  PumpSimulator(const std::string& model_path, SimulationOptions opt);
  // The next identification run (run_id "<pump>/sim-<n>").
  RunRecording identification_run();

 private:
  PlantModel plant_;
  SimulationOptions opt_;
  int runs_ = 0;
};

}  // namespace ambdiag::agent
