// Operating variability and developing faults of the simulated pump
// (edge_agent/simulate.h, docs/simulation.md "Operating variability and
// developing faults"): each run's speed and seal drift are drawn as stated,
// deterministic per seed, and the run carries the FRF of that pump; a fault
// applies its value from the stated run and grows linearly; a fault at its
// healthy value is exactly the healthy pump; the truth rides in run.json
// and the server's header parser keeps it byte for byte.
#include "ambdiag/edge_agent/simulate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <set>

#include "ambdiag/algorithms/estimation/frf_estimation.h"
#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/core/error.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/storage/historian.h"
#include "simulate_support.h"
#include "test_support.h"

namespace ambdiag::agent {
namespace {

bool is_seal(const Link& l) { return l.kind == "seal" || l.kind == "balance_piston"; }

TEST(OperatingVariability, SpeedSpreadGivesEachRunItsOwnSpeedAndThePlantAtIt) {
  SimulationOptions o = small(false);
  o.speed_spread_pct = 5;
  PumpSimulator sim(model_path(), o);
  const double model_rpm = 2950.0;
  std::set<double> speeds;
  for (int n = 1; n <= 2; ++n) {
    const RunRecording run = sim.identification_run();
    reported("run speed rpm", run.speed_rpm);
    reported("loop build s", sim.last_rebuild_s());
    EXPECT_GE(run.speed_rpm, model_rpm * 0.95);
    EXPECT_LE(run.speed_rpm, model_rpm * 1.05);
    speeds.insert(run.speed_rpm);
    EXPECT_EQ(sim.plant().speed_rpm, run.speed_rpm);
    EXPECT_EQ(run.extra.at("simulation").at("speed_rpm").get<double>(), run.speed_rpm);
    EXPECT_EQ(run.extra.at("simulation").at("run").get<int64_t>(), n);
    const int ch = run.channel_index("speed");
    ASSERT_GE(ch, 0);
    EXPECT_EQ(run.at(0, ch), static_cast<float>(run.speed_rpm));
    EXPECT_EQ(run.at(run.frame_count() - 1, ch), static_cast<float>(run.speed_rpm));
    // The run carries the FRF at its own speed (seal tables ~ rpm^2,
    // gyroscopics), not the model speed's.
    const FrfEstimate est = estimate_frf(run);
    const double own = nrmse(est.frf, model_frf(sim.plant(), est.frf));
    PlantModel at_model_speed = sim.plant();
    at_model_speed.speed_rpm = model_rpm;
    const double other = nrmse(est.frf, model_frf(at_model_speed, est.frf));
    EXPECT_LT(reported("nrmse vs plant at run speed", own), 1e-4);
    if (std::abs(run.speed_rpm / model_rpm - 1) > 0.01) {
      EXPECT_GT(reported("nrmse vs plant at model speed", other), 20 * own);
    }
  }
  EXPECT_EQ(speeds.size(), 2u);

  // Deterministic per seed, different for another seed; over many runs the
  // factors fill the stated band and no more.
  PumpSimulator again(model_path(), o);
  SimulationOptions o2 = o;
  o2.seed = 2;
  PumpSimulator other_seed(model_path(), o2);
  double lo = 2, hi = 0, sum = 0;
  const int n_runs = 400;
  for (int n = 1; n <= n_runs; ++n) {
    const double f = sim.operating_state(n).speed_factor;
    EXPECT_EQ(again.operating_state(n).speed_factor, f);
    EXPECT_NE(other_seed.operating_state(n).speed_factor, f);
    lo = std::min(lo, f), hi = std::max(hi, f), sum += f;
  }
  EXPECT_GE(lo, 0.95);
  EXPECT_LE(hi, 1.05);
  EXPECT_LT(lo, 0.955);  // U(-5 %, 5 %): 400 draws reach within 0.5 % of each end
  EXPECT_GT(hi, 1.045);
  EXPECT_NEAR(sum / n_runs, 1.0, 0.005);  // sigma of the mean 0.05 / sqrt(3) / sqrt(400) = 1.4e-3
}

TEST(OperatingVariability, SealDriftScalesEverySealCoefficientByTheRunsFactor) {
  SimulationOptions o = small(false);
  o.seal_drift_pct = 5;
  o.seal_drift_link_pct = 1;
  PumpSimulator sim(model_path(), o);
  const PlantModel base = read_plant_file(model_path());
  const RunRecording run = sim.identification_run();
  const OperatingState& st = sim.state();
  ASSERT_EQ(st.seal_factor.size(), 2u);  // impeller_seal, balance_piston
  reported("seal drift d", st.seal_drift);
  for (size_t i = 0; i < base.links.size(); ++i) {
    const Link& b = base.links[i];
    const Link& p = sim.plant().links[i];
    double factor = 1.0;
    for (const auto& [name, f] : st.seal_factor)
      if (name == b.name) factor = f;
    EXPECT_EQ(is_seal(b), factor != 1.0) << b.name;
    for (size_t c = 0; c < b.coef.size(); ++c) EXPECT_DOUBLE_EQ(p.coef[c], b.coef[c] * factor) << b.name << " " << c;
    ASSERT_EQ(p.table.size(), b.table.size());
    for (size_t r = 0; r < b.table.size(); ++r)
      for (size_t c = 0; c < b.table[r].values.size(); ++c)
        if (b.table[r].values[c]) {
          EXPECT_DOUBLE_EQ(*p.table[r].values[c], *b.table[r].values[c] * factor) << b.name;
        }
  }
  // The estimated FRF moves away from the model's by what the drifted model
  // says (the seal-dominated modes), not by noise or anything else.
  const FrfEstimate est = estimate_frf(run);
  const double expected = nrmse(model_frf(sim.plant(), est.frf), model_frf(base, est.frf));
  reported("nrmse drifted vs base model", expected);
  EXPECT_LT(reported("nrmse est vs drifted model", nrmse(est.frf, model_frf(sim.plant(), est.frf))), 1e-4);
  EXPECT_GT(expected, 1e-3);
  EXPECT_NEAR(nrmse(est.frf, model_frf(base, est.frf)) / expected, 1.0, 0.1);

  // The draws: d ~ N(0, 5 %) common, an independent 1 % per link, cut at 3 sigma.
  double s_d = 0, s_l = 0;
  const int n_runs = 400;
  for (int n = 1; n <= n_runs; ++n) {
    const OperatingState s = sim.operating_state(n);
    EXPECT_LE(std::abs(s.seal_drift), 0.15 + 1e-12);
    s_d += s.seal_drift * s.seal_drift;
    for (const auto& [name, f] : s.seal_factor) {
      const double d_link = f / (1 + s.seal_drift) - 1;
      EXPECT_LE(std::abs(d_link), 0.03 + 1e-12) << name;
      s_l += d_link * d_link;
    }
  }
  EXPECT_NEAR(reported("rms d", std::sqrt(s_d / n_runs)), 0.05, 0.006);
  EXPECT_NEAR(reported("rms d_link", std::sqrt(s_l / (2 * n_runs))), 0.01, 0.001);
}

// balance_piston_wear=1.6@run2: run 1 is the healthy simulator's run to the
// last bit (same loop, same noise), run 2 is the worn pump's.
TEST(DevelopingFault, OnsetAppliesTheValueFromTheStatedRun) {
  SimulationOptions o = small(false);
  o.loop.displacement_noise_m = 0.05e-6;  // noise too: run 1 must share it
  PumpSimulator healthy(model_path(), o);
  o.faults = {"balance_piston_wear=1.6@run2"};
  PumpSimulator sim(model_path(), o);
  const RunRecording h1 = healthy.identification_run(), f1 = sim.identification_run();
  EXPECT_EQ(f1.samples, h1.samples);
  EXPECT_FALSE(sim.state().faults.at(0).active);
  EXPECT_EQ(sim.state().faults.at(0).value, 1.0);
  const auto& j1 = f1.extra.at("simulation").at("faults").at(0);
  EXPECT_EQ(j1.at("spec"), "balance_piston_wear=1.6@run2");
  EXPECT_EQ(j1.at("active"), false);

  // Noise free, so the FRF of run 2 can be held to the worn model's.
  SimulationOptions q = small(false);
  q.faults = {"balance_piston_wear=1.6@run2"};
  PumpSimulator sim2(model_path(), q);
  sim2.identification_run();
  const RunRecording f2 = sim2.identification_run();
  EXPECT_TRUE(sim2.state().faults.at(0).active);
  EXPECT_EQ(f2.extra.at("simulation").at("faults").at(0).at("value").get<double>(), 1.6);
  const PlantModel base = read_plant_file(model_path());
  for (size_t i = 0; i < base.links.size(); ++i) {
    const double want = base.links[i].kind == "balance_piston" ? base.links[i].get(LinkCoef::kxx) / 1.6
                                                               : base.links[i].get(LinkCoef::kxx);
    EXPECT_DOUBLE_EQ(sim2.plant().links[i].get(LinkCoef::kxx), want) << base.links[i].name;
  }
  const FrfEstimate est = estimate_frf(f2);
  EXPECT_LT(reported("nrmse run 2 vs worn model", nrmse(est.frf, model_frf(sim2.plant(), est.frf))), 1e-4);
  EXPECT_GT(reported("nrmse run 2 vs healthy model", nrmse(est.frf, model_frf(base, est.frf))), 1e-2);
}

TEST(DevelopingFault, RampIsLinearFromTheFirstToTheLastRun) {
  SimulationOptions o = small(false);
  o.runs = 5;
  o.faults = {"impeller_seal_wear=1..2", "balance_piston_wear=1.2..1.6@run3..5", "sensor_fault@run3",
              "actuator_fault=0.5..0.9@run2"};
  PumpSimulator sim(model_path(), o);
  const double seal[] = {1, 1.25, 1.5, 1.75, 2, 2}, piston[] = {1, 1, 1.2, 1.4, 1.6, 1.6},
               sensor[] = {1, 1, 0.8, 0.8, 0.8, 0.8},
               actuator[] = {1, 0.5, 0.5 + 0.4 / 3, 0.5 + 0.8 / 3, 0.9, 0.9};  // runs 2..5
  for (int n = 1; n <= 6; ++n) {
    const OperatingState s = sim.operating_state(n);
    ASSERT_EQ(s.faults.size(), 4u);
    EXPECT_NEAR(s.faults[0].value, seal[n - 1], 1e-12) << n;
    EXPECT_NEAR(s.faults[1].value, piston[n - 1], 1e-12) << n;
    EXPECT_NEAR(s.faults[2].value, sensor[n - 1], 1e-12) << n;
    EXPECT_NEAR(s.faults[3].value, actuator[n - 1], 1e-12) << n;
    EXPECT_EQ(s.faults[1].active, n >= 3) << n;
  }
  // The plant of run 4: seal / 1.75, piston / 1.4.
  sim.set_operating_state(4);
  const PlantModel base = read_plant_file(model_path());
  for (size_t i = 0; i < base.links.size(); ++i) {
    const double c = base.links[i].kind == "seal" ? 1.75 : base.links[i].kind == "balance_piston" ? 1.4 : 1.0;
    EXPECT_NEAR(sim.plant().links[i].get(LinkCoef::cxx), base.links[i].get(LinkCoef::cxx) / c, 1e-9) << base.links[i].name;
  }
}

// A fault at its healthy value is not a small fault: it is the healthy pump
// (no renamed materials, no gain vectors), and the runs are bit for bit the
// healthy simulator's.
TEST(DevelopingFault, HealthyValueIsExactlyTheHealthyPump) {
  SimulationOptions o = small(false);
  o.loop.displacement_noise_m = 0.05e-6;
  o.loop.current_noise_a = 2e-3;
  o.runs = 2;
  PumpSimulator healthy(model_path(), o);
  o.faults = {"balance_piston_wear=1", "rotor_crack=1.0", "shaft_nut_loosening=1", "sensor_fault=1",
              "actuator_fault=1@run1", "dry_run=1..1", "impeller_seal_wear=1.0..1.0@run1..2"};
  PumpSimulator sim(model_path(), o);
  for (int n = 1; n <= 2; ++n) {
    const RunRecording a = healthy.identification_run(), b = sim.identification_run();
    EXPECT_EQ(plant_to_json(sim.plant()), plant_to_json(healthy.plant())) << n;
    EXPECT_EQ(a.samples, b.samples) << n;
    for (const auto& f : sim.state().faults) EXPECT_FALSE(f.active) << f.spec;
  }
}

TEST(DevelopingFault, RefusesMalformedSchedulesNamingThem) {
  for (const std::string bad : {"dry_run=", "dry_run=0.5@run0", "dry_run=0.5@5", "dry_run=0.5@run", "dry_run=0.5@run2x",
                                "impeller_seal_wear=1.5..1.2@run3..2", "dry_run=0.5@run2..4", "dry_run=a..b",
                                "dry_run=-1", "dry_run=0.5..", "bearing_fire=1", "dry_run=0.5@run+2"}) {
    try {
      parse_fault_schedule(bad);
      ADD_FAILURE() << bad << " accepted";
    } catch (const InputError& e) {
      const std::string name = bad.substr(0, bad.find('='));
      EXPECT_NE(std::string(e.what()).find(name == "bearing_fire" ? name : bad), std::string::npos) << e.what();
    }
  }
  const FaultSchedule f = parse_fault_schedule("balance_piston_wear=1.0..1.6@run5..9");
  EXPECT_EQ(f.name, "balance_piston_wear");
  EXPECT_EQ(f.value, 1.0);
  EXPECT_EQ(f.end_value, 1.6);
  EXPECT_EQ(f.from_run, 5);
  EXPECT_EQ(f.to_run, 9);
  // Known only against the plant or the run count: the simulator refuses.
  SimulationOptions o = small(false);
  o.faults = {"impeller_seal_wear=1..2"};  // a ramp with no last run
  EXPECT_THROW(PumpSimulator(model_path(), o), InputError);
  o.runs = 3;
  o.faults = {"impeller_seal_wear=1..9"};  // the end beyond clearance_factor 8
  EXPECT_THROW(PumpSimulator(model_path(), o), InputError);
  o.faults = {"impeller_seal_wear=1..2@run4"};  // starts after the last run
  EXPECT_THROW(PumpSimulator(model_path(), o), InputError);
  o.faults = {};
  o.speed_spread_pct = 25;
  EXPECT_THROW(PumpSimulator(model_path(), o), InputError);
}

// The truth rides in run.json under "simulation"; the server's header
// parser (storage::run_header_from_json) accepts it and keeps the text as
// sent; a recording written and read back keeps it too.
TEST(OperatingVariability, RunJsonCarriesTheTruthAndTheServerKeepsIt) {
  SimulationOptions o = small(false);
  o.speed_spread_pct = 3;
  o.seal_drift_pct = 4;
  o.faults = {"impeller_seal_wear=1.5@run1"};
  PumpSimulator sim(model_path(), o);
  const RunRecording run = sim.identification_run();
  const std::string text = run_to_json(run).dump();
  const storage::RunHeader h = storage::run_header_from_json(text);
  EXPECT_EQ(h.header_json, text);
  EXPECT_EQ(h.speed_rpm, run.speed_rpm);
  const nlohmann::json truth = nlohmann::json::parse(h.header_json).at("simulation");
  EXPECT_EQ(truth, sim.state().to_json());
  EXPECT_EQ(truth.at("seal_factors").size(), 2u);
  EXPECT_EQ(truth.at("faults").at(0).at("value").get<double>(), 1.5);
  const auto dir = ambdiag::testing::scratch_dir() / "run";
  write_run(dir.string(), run);
  EXPECT_EQ(read_run(dir.string()).extra.at("simulation"), truth);
}

// Snapshots of a second simulator (its own noise seed, the runs' operating
// seed) show the pump of the run it is told to follow.
TEST(OperatingVariability, SnapshotsFollowTheRunsPump) {
  SimulationOptions o = small(false);
  o.speed_spread_pct = 5;
  o.monitoring_s = 0.1;
  PumpSimulator runs(model_path(), o);
  SimulationOptions m = o;
  m.seed = o.seed + 1;
  m.operating_seed = o.seed;
  PumpSimulator snapshots(model_path(), m);
  for (int n : {1, 3}) {
    snapshots.set_operating_state(n);
    EXPECT_EQ(snapshots.monitoring_snapshot().speed_rpm, runs.operating_state(n).speed_rpm) << n;
    EXPECT_EQ(snapshots.plant().speed_rpm, runs.operating_state(n).speed_rpm) << n;
  }
  EXPECT_NE(runs.operating_state(1).speed_rpm, runs.operating_state(3).speed_rpm);
}

}  // namespace
}  // namespace ambdiag::agent
