// The fleet check of issue 16 (fleet_fixture.h) over a fleet: two machines,
// healthy pumps and pumps developing faults (label slow: minutes).
#include "fleet_fixture.h"

namespace ambdiag::testing {
namespace {

// The fleet: both machines, four healthy pumps and three developing faults
// (faults start at run 5, so runs 4 of those pumps are healthy runs past
// the reference, too), one healthy pump per machine with each seal's own
// drift on top of the common one. Four agents at a time, a run every 8 s
// each (2 s of simulation on one core, streaming, and room for the
// server's analyses on the second core): a pump's reference is set while
// its later runs are still coming.
TEST_F(FleetTest, TwoMachinesHealthyAndFaultyPumps) {
  const std::vector<PumpSpec> pumps = {
      {"R-1", reference_model, 6, 3.0, 1.0, 11, {}},
      {"R-2", reference_model, 6, 2.0, 2.0, 12, {}, 1.0},
      {"R-3", reference_model, 7, 2.5, 1.5, 13, {"balance_piston_wear=1.2..1.6@run5..7"}},
      {"S-1", second_model, 6, 3.0, 1.5, 21, {}},
      {"S-2", second_model, 6, 2.0, 2.0, 22, {}, 1.0},
      {"S-3", second_model, 7, 2.5, 1.0, 23, {"impeller_seal_wear=1.3..1.8@run5..7"}},
      {"S-4", second_model, 7, 2.0, 1.5, 24, {"dry_run=0.7..0.3@run5..7"}},
  };
  const auto runs = run_fleet(pumps, 4, 8.0);
  ASSERT_EQ(runs.size(), 45u);
  const Counts c = check(runs);
  check_alarms(runs);
  EXPECT_EQ(c.healthy, 4 * 6 + 3 * 4);
  EXPECT_EQ(c.faulty_clear, 8);  // R-3 runs 6, 7 (1.4, 1.6); S-3 and S-4 runs 5-7
  // The runs of a pump 8 s after its third arrive with the reference in
  // place (it is set within a poll of 0.2 s of the proposal; measured: all
  // 24 runs 4..): at least runs 6.. of every pump, 4 x 1 + 3 x 2, unless
  // the machine is badly overloaded.
  EXPECT_GE(c.on_arrival, 10);
}


// The simulator's other faults on both machines, under the same
// variability: a sensor and an actuator gain, a crack next to the impeller
// and the impeller's hub joint, each from run 4, diagnosed with its
// location and an interval holding the truth; 10 x the unbalance is not in
// the FRF and must not be detected. (The crack on the second machine was
// diagnosed as the hub joint until crack_refine went from 3 to 6.)
TEST_F(FleetTest, ShaftAndChannelFaultsOfBothMachines) {
  const std::vector<PumpSpec> pumps = {
      {"X-1", reference_model, 5, 2.5, 1.5, 31, {"sensor_fault=0.8@run4"}},
      {"X-2", second_model, 5, 2.5, 1.5, 32, {"rotor_crack=0.5@run4"}},
      {"X-3", reference_model, 5, 2.5, 1.5, 33, {"shaft_nut_loosening=0.5@run4"}},
      {"X-4", second_model, 5, 2.5, 1.5, 34, {"unbalance@run4"}},
      {"X-5", second_model, 5, 2.5, 1.5, 35, {"actuator_fault=0.7@run4"}},
      {"X-6", reference_model, 5, 2.5, 1.5, 36, {"rotor_crack=0.6@run4"}},
  };
  const auto runs = run_fleet(pumps, 3, 6.0);
  ASSERT_EQ(runs.size(), 30u);
  const Counts c = check(runs);
  check_alarms(runs);
  EXPECT_EQ(c.healthy, 6 * 3);
  EXPECT_EQ(c.faulty_clear, 5 * 2);
  EXPECT_EQ(c.frf_unchanged, 2);
}
}  // namespace
}  // namespace ambdiag::testing
