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
// Operating variability (docs/simulation.md, "Operating variability"): per
// identification run n, from a generator seeded with (operating seed, n)
// alone, so run n's pump is the same whatever ran before and in the
// snapshot simulator too:
//   speed    = model speed x (1 + v speed_spread_pct / 100), v ~ U(-1, 1):
//              gyroscopics, the links' speed tables and the 1x unbalance
//              (u Omega^2, u fixed) at that speed;
//   seals    = every coefficient and speed-table value of every link of
//              kind seal or balance_piston x (1 + d)(1 + d_l), d ~ N(0,
//              seal_drift_pct / 100) common to the run, d_l ~ N(0,
//              seal_drift_link_pct / 100) per link, both cut at 3 sigma.
// A run whose pump differs from the previous run's rebuilds the discrete
// loop (a matrix exponential; the loop starts at rest and the settle
// periods take the start transient); an unchanged pump keeps the loop, its
// state and its noise stream, so the defaults behave as before.
//
// Faults by name, NAME or NAME=VALUE, developing over the runs with
// @runK (onset) or A..B (linear growth); FaultSchedule below
// (docs/simulation.md):
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
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/simulation/amb_loop.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/run_recording.h"

namespace ambdiag::agent {

// One --fault argument:
//   NAME                   the fault at its default value from run 1 on
//   NAME=V                 V from run 1 on
//   NAME=A..B              linear from A at the first run to B at the last
//                          run of SimulationOptions::runs (--runs N)
//   ...@runK               healthy before run K, the value above from run K
//                          on (a ramp then goes from A at run K to B at N)
//   NAME=A..B@runK..M      healthy before K, A at K to B at M, B after M
//                          (needs no --runs)
// Runs count identification runs from 1. Healthy is the parameter's
// nominal value (1 for the factors and gains, the residual unbalance);
// a fault at its healthy value leaves the pump exactly healthy.
struct FaultSchedule {
  std::string text;                     // as given
  std::string name;
  std::optional<double> value;          // unset: the fault's default
  std::optional<double> end_value;      // set: a ramp from value to end_value
  int64_t from_run = 1;
  std::optional<int64_t> to_run;        // ramp end; unset: SimulationOptions::runs
};
// Throws InputError naming `text` for malformed syntax or an unknown fault
// name (the agent's command line turns it into a usage error, exit 2).
FaultSchedule parse_fault_schedule(const std::string& text);
// The fault names the simulator knows.
const std::vector<std::string>& simulated_fault_names();

// The truth behind one identification run, written into its run.json as
// "simulation" (run_to_json keeps unknown keys; see to_json).
struct OperatingState {
  int64_t run = 1;
  double speed_factor = 1.0;                                // speed / model speed
  double speed_rpm = 0.0;
  double seal_drift = 0.0;                                  // common d
  std::vector<std::pair<std::string, double>> seal_factor;  // link name -> (1 + d)(1 + d_l)
  struct Fault {
    std::string spec, name;
    double value = 0.0;    // in force at this run (the healthy value before the onset)
    bool active = false;   // value differs from the healthy one
  };
  std::vector<Fault> faults;
  // The pump (speed, seals, fault values) is the same.
  bool same_pump(const OperatingState& o) const;
  nlohmann::json to_json() const;
};

struct SimulationOptions {
  std::string pump_id;
  std::vector<std::string> faults;       // FaultSchedule syntax
  double speed_spread_pct = 0.0;         // 0: every run at the model speed
  double seal_drift_pct = 0.0;           // common seal drift, 1 sigma
  double seal_drift_link_pct = 0.0;      // independent part per link, 1 sigma
  int64_t runs = 0;                      // identification runs planned (ramp end); 0: not known
  std::optional<uint64_t> operating_seed;  // speed and drift draws; unset: seed
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
  // Throws InputError for a bad model file, an unknown fault name or value
  // (a ramp's two ends are checked), a ramp without an end run, or bad
  // options.
  PumpSimulator(const std::string& model_path, SimulationOptions opt);
  PumpSimulator(PlantModel plant, SimulationOptions opt);
  ~PumpSimulator();
  // The next identification run (run_id "<pump>/sim-<n>-<UTC time>"), of the
  // pump as operating_state(n) says, which its run.json carries as
  // "simulation".
  RunRecording identification_run();
  // The pump as in identification run n from now on (snapshots of a second
  // simulator follow the runs this way); rebuilds the loop if it differs.
  void set_operating_state(int64_t run);
  Snapshot monitoring_snapshot();
  // Run n's draws and fault values; cheap (no loop), deterministic in the
  // operating seed and n.
  OperatingState operating_state(int64_t run) const;
  const OperatingState& state() const { return state_; }  // of the current pump
  const PlantModel& plant() const { return plant_; }       // the current pump: speed, seals, faults applied
  const AmbLoop& loop() const { return *loop_; }
  // Wall time of the loop build for the current pump (0: the previous
  // pump's loop was kept).
  double last_rebuild_s() const { return last_rebuild_s_; }

 private:
  struct ScheduledFault;
  PlantModel plant_of(const OperatingState& st) const;
  AmbLoopOptions loop_options_of(const OperatingState& st) const;
  void build_loop(const OperatingState& st, uint64_t noise_seed);

  RunRecording new_run(const std::string& kind);
  void append(RunRecording& run, const Eigen::MatrixXd& r, const Eigen::MatrixXd& f, const Eigen::MatrixXd& x) const;
  RunRecording multisine_run();
  RunRecording stepsine_run();

  PlantModel base_;   // as read, healthy, at the model speed
  PlantModel plant_;  // the current pump
  SimulationOptions opt_;
  std::vector<ScheduledFault> faults_;
  std::vector<int> seal_links_;  // links of kind seal and balance_piston
  OperatingState state_;
  std::unique_ptr<AmbLoop> loop_;
  double last_rebuild_s_ = 0.0;
  int runs_ = 0;
};

}  // namespace ambdiag::agent
