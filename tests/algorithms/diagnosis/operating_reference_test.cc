// Detection under real operating conditions (operating_reference.h): runs at
// other speeds and with a normal seal drift are not faults; a worn balance
// piston is, at any speed.
#include <gtest/gtest.h>

#include <cmath>
#include <ctime>
#include <random>

#include "ambdiag/algorithms/diagnosis/diagnosis.h"
#include "ambdiag/algorithms/diagnosis/operating_reference.h"
#include "ambdiag/core/error.h"
#include "diagnosis_support.h"
#include "operating_support.h"
#include "second_pump.h"
#include "test_support.h"

namespace ambdiag {
namespace {

using testing::data_file;
using testing::Operation;
using testing::reference_plant;
using testing::SealDrift;
using testing::shared_like;

const FaultHypothesis& balance_piston_hypothesis(const std::vector<FaultHypothesis>& hs) {
  for (const auto& h : hs)
    if (h.kind == FaultKind::balance_piston_wear) return h;
  throw std::logic_error("no balance piston");
}

std::vector<FrfData> shared_references(int n) {
  std::vector<FrfData> v;
  for (int i = 1; i <= n; ++i) v.push_back(read_frf_csv(data_file("reference_pump/frf_ref_" + std::to_string(i) + ".csv").string()));
  return v;
}

// Three healthy runs under normal operation (speed +-3 %, seal drift).
std::vector<FrfData> simulated_references(const PlantModel& plant, const FrfData& like, const Operation& op, std::mt19937_64& rng) {
  std::vector<FrfData> refs;
  for (int i = 0; i < 3; ++i) refs.push_back(testing::healthy_run(plant, like, op, rng));
  return refs;
}

TEST(OperatingReference, LearnsSpeedsDriftAndANoiseLevelFromThreeRuns) {
  const PlantModel plant = reference_plant();
  const FrfData like = shared_like();
  std::mt19937_64 rng(16001);
  const auto refs = simulated_references(plant, like, Operation{}, rng);
  const OperatingReference ref = learn_operating_reference(plant, refs);
  ASSERT_EQ(ref.runs.size(), 3u);
  ASSERT_EQ(ref.nuisance_links.size(), 2u);  // impeller_seal, balance_piston
  for (size_t i = 0; i < 3; ++i) EXPECT_EQ(ref.runs[i].speed_rpm, *refs[i].speed_rpm);
  EXPECT_GE(ref.common_sd, 0.03);  // the floors
  EXPECT_GE(ref.link_sd, 0.01);
  for (const auto& e : ref.entries) {
    EXPECT_NEAR(e.scatter_ratio, 1.0, 0.1) << e.output << "/" << e.input;  // the residuals scatter as sigma says
    EXPECT_EQ(e.kappa, 1.0) << e.output << "/" << e.input;
  }
  for (const auto& r : ref.runs) EXPECT_NEAR(r.chi2 / r.values, 2.0 / 3.0, 0.05);  // (n - 1) / n of the noise
}

// The false-alarm rate is alpha: healthy runs at speeds +-3 % and with seal
// drift at the floors' size (common 3 %, own 1 %: the spread the test
// assumes), each against references of three such runs (10 machines x 15
// runs). Residual and drift tests each at alpha_each = 1 - sqrt(1 - alpha).
TEST(OperatingReference, FalseAlarmRateMatchesAlphaUnderSpeedAndSealDrift) {
  const PlantModel plant = reference_plant();
  const FrfData like = shared_like();
  std::mt19937_64 rng(16002);
  Operation op;
  op.common_sd = 0.03;
  op.own_sd = 0.01;
  DiagnosisOptions opt;
  opt.alpha = 0.05;
  opt.detect_only = true;
  int alarms = 0, residual = 0, drift = 0, runs = 0;
  double cpu_s = 0.0;
  for (int m = 0; m < 10; ++m) {
    const OperatingReference ref = learn_operating_reference(plant, simulated_references(plant, like, op, rng));
    for (int k = 0; k < 15; ++k) {
      const FrfData run = testing::healthy_run(plant, like, op, rng);
      const std::clock_t t0 = std::clock();
      const DiagnosisResult r = diagnose(plant, ref, run, opt);
      cpu_s += static_cast<double>(std::clock() - t0) / CLOCKS_PER_SEC;
      alarms += r.detected;
      residual += r.operating.residual_detected;
      drift += r.operating.drift_detected;
      EXPECT_EQ(r.detected, r.p_value < opt.alpha);
      EXPECT_EQ(r.detected, r.statistic > r.threshold);
      ++runs;
    }
  }
  RecordProperty("alarms_of_150_at_alpha_0.05", alarms);
  RecordProperty("residual_alarms", residual);
  RecordProperty("drift_alarms", drift);
  RecordProperty("detection_cpu_ms_per_run", static_cast<int>(1000.0 * cpu_s / runs));
  std::printf("alarms %d of %d (residual %d, drift %d), detection %.1f ms CPU per run\n", alarms, runs, residual, drift,
              1000.0 * cpu_s / runs);
  // Binomial(150, 0.05): mean 7.5, sd 2.7; residual test alone at 0.0253: 3.8 +- 1.9.
  EXPECT_GE(alarms, 1);
  EXPECT_LE(alarms, 16);
  EXPECT_LE(residual, 10);
  EXPECT_LT(cpu_s / runs, 0.3);
}

// The bug: a common seal drift of 3 % at the references' speed is
// diagnosed as a fault by the same-speed path; the operating path does not
// fire.
TEST(OperatingReference, ThreePercentSealDriftIsNotDetected) {
  const PlantModel plant = reference_plant();
  const FrfData like = shared_like();
  std::mt19937_64 rng(16003);
  std::vector<FrfData> refs;
  for (int i = 0; i < 3; ++i) refs.push_back(testing::simulate_run(plant, like, 2950.0, rng));
  const FrfData run = testing::simulate_run(testing::drifted(plant, SealDrift{0.03, {}}), like, 2950.0, rng);
  DiagnosisOptions opt;
  opt.alpha = 1e-4;
  const DiagnosisResult old = diagnose(plant, reference_statistics(refs), run, opt);
  EXPECT_TRUE(old.detected) << "the old path should fire on a 3 % seal drift";
  const DiagnosisResult r = diagnose(plant, learn_operating_reference(plant, refs), run, opt);
  EXPECT_FALSE(r.detected) << "residual p " << r.operating.residual_p_value << ", drift " << r.operating.drift_statistic;
  EXPECT_TRUE(r.faults.empty());
  std::printf("3 %% drift: old path T/threshold %.2f (first fault %s %.4f); new path p %.3f (residual p %.3f, drift D %.2f, %+.3f %% %+.3f %%)\n",
              old.statistic / old.threshold, old.faults.empty() ? "-" : old.faults.front().name.c_str(),
              old.faults.empty() ? 0.0 : old.faults.front().value, r.p_value, r.operating.residual_p_value, r.operating.drift_statistic,
              100.0 * std::expm1(r.operating.nuisance[0].log_factor), 100.0 * std::expm1(r.operating.nuisance[1].log_factor));
  ASSERT_EQ(r.operating.nuisance.size(), 2u);
  for (const auto& nu : r.operating.nuisance) EXPECT_NEAR(nu.log_factor, std::log(1.03), 0.005) << nu.link;
}

// A run 3 % faster than its references: the same-speed path refuses it; the
// operating path evaluates the model at the run's speed and finds nothing.
TEST(OperatingReference, RunThreePercentFasterIsAcceptedAndNotDetected) {
  const PlantModel plant = reference_plant();
  const FrfData like = shared_like();
  std::mt19937_64 rng(16004);
  std::vector<FrfData> refs;
  for (int i = 0; i < 3; ++i) refs.push_back(testing::simulate_run(plant, like, 2950.0, rng));
  const FrfData run = testing::simulate_run(plant, like, 2950.0 * 1.03, rng);
  EXPECT_THROW(diagnose(plant, reference_statistics(refs), run), InputError);
  DiagnosisOptions opt;
  opt.alpha = 1e-4;
  const DiagnosisResult r = diagnose(plant, learn_operating_reference(plant, refs), run, opt);
  EXPECT_FALSE(r.detected) << "residual p " << r.operating.residual_p_value << ", drift p " << r.operating.drift_p_value;
  EXPECT_DOUBLE_EQ(r.operating.speed_rpm, 2950.0 * 1.03);
  std::printf("3 %% faster: p %.3f (residual T/dof %.4f, drift D %.2f)\n", r.p_value,
              r.operating.residual_statistic / r.operating.residual_dof, r.operating.drift_statistic);
}

// The fault: balance piston clearance 1.3 x nominal, at 2 % above
// the references' speeds, with the seals drifted by 1 %: detected, and
// diagnosed as balance piston wear with 1.3 inside its interval.
TEST(OperatingReference, BalancePistonWearAtAnotherSpeedWithSealDriftIsDiagnosed) {
  const PlantModel plant = reference_plant();
  const FrfData like = shared_like();
  std::mt19937_64 rng(16005);
  const auto refs = simulated_references(plant, like, Operation{}, rng);
  const OperatingReference ref = learn_operating_reference(plant, refs);
  const auto hyps = fault_hypotheses(plant);
  const PlantModel truth = apply_fault(testing::drifted(plant, SealDrift{0.01, {}}), balance_piston_hypothesis(hyps), 1.3);
  const FrfData run = testing::simulate_run(truth, like, 2950.0 * 1.02, rng);
  DiagnosisOptions opt;
  opt.alpha = kRecommendedAlphaPerRun;
  const DiagnosisResult r = diagnose(plant, ref, run, opt);
  ASSERT_TRUE(r.detected);
  ASSERT_FALSE(r.faults.empty());
  const FaultEstimate& f = r.faults.front();
  EXPECT_EQ(f.name, "balance_piston_wear");
  EXPECT_LE(f.ci_lo, 1.3);
  EXPECT_GE(f.ci_hi, 1.3);
  EXPECT_NEAR(f.value, 1.3, 0.05);
  EXPECT_TRUE(r.explained);
  std::printf("balance piston: drift D %.1f (threshold %.1f), residual T/thr %.3f, clearance %.4f [%.4f, %.4f], evaluations %d\n",
              r.operating.drift_statistic, r.operating.drift_threshold, r.operating.residual_statistic / r.operating.residual_threshold, f.value, f.ci_lo, f.ci_hi,
              r.evaluations);
  for (size_t i = 0; i < 3 && i < r.faults.size(); ++i)
    std::printf("  %s %s %.4f chi2 %.1f\n", r.faults[i].name.c_str(), r.faults[i].location.c_str(), r.faults[i].value, r.faults[i].chi2);
}

// The other annular seal worn, at 2 % below the references' speeds, seals
// drifted by 1 %: the drift of one link is told from the other's wear.
TEST(OperatingReference, ImpellerSealWearAtAnotherSpeedIsNotTakenForTheBalancePiston) {
  const PlantModel plant = reference_plant();
  const FrfData like = shared_like();
  std::mt19937_64 rng(16007);
  const OperatingReference ref = learn_operating_reference(plant, simulated_references(plant, like, Operation{}, rng));
  const FaultHypothesis* seal = nullptr;
  const auto hyps = fault_hypotheses(plant);
  for (const auto& h : hyps)
    if (h.kind == FaultKind::impeller_seal_wear) seal = &h;
  ASSERT_NE(seal, nullptr);
  const PlantModel truth = apply_fault(testing::drifted(plant, SealDrift{0.01, {}}), *seal, 1.3);
  DiagnosisOptions opt;
  opt.alpha = kRecommendedAlphaPerRun;
  const DiagnosisResult r = diagnose(plant, ref, testing::simulate_run(truth, like, 2950.0 * 0.98, rng), opt);
  ASSERT_TRUE(r.detected);
  ASSERT_FALSE(r.faults.empty());
  EXPECT_EQ(r.faults.front().name, "impeller_seal_wear");
  EXPECT_LE(r.faults.front().ci_lo, 1.3);
  EXPECT_GE(r.faults.front().ci_hi, 1.3);
  std::printf("impeller seal: drift D %.1f, residual T/thr %.3f; %s %.4f [%.4f, %.4f]\n", r.operating.drift_statistic,
              r.operating.residual_statistic / r.operating.residual_threshold, r.faults.front().name.c_str(), r.faults.front().value,
              r.faults.front().ci_lo, r.faults.front().ci_hi);
}

// A change no fault model and no seal drift has (a housing resonance 8 %
// higher, at another speed): detected by the residual test and `unknown`,
// not forced into a drift or a seal fault.
TEST(OperatingReference, UnmodelledChangeIsUnknown) {
  const PlantModel plant = reference_plant();
  const FrfData like = shared_like();
  std::mt19937_64 rng(16010);
  const OperatingReference ref = learn_operating_reference(plant, simulated_references(plant, like, Operation{}, rng));
  PlantModel changed = plant;
  changed.housings.at(0).f_hz *= 1.08;
  const DiagnosisResult r = diagnose(plant, ref, testing::simulate_run(changed, like, 2950.0 * 1.01, rng));
  ASSERT_TRUE(r.detected);
  EXPECT_TRUE(r.operating.residual_detected);
  ASSERT_FALSE(r.faults.empty());
  EXPECT_EQ(r.faults.front().name, "unknown");
  EXPECT_FALSE(r.explained);
}

// The shared cases (independent generator) through the operating path,
// against three of the shared reference runs.
TEST(OperatingReference, SharedFaultCasesAreDetectedAndDiagnosed) {
  const PlantModel plant = reference_plant();
  const OperatingReference ref = learn_operating_reference(plant, shared_references(3));
  struct Case {
    const char* dir;
    const char* first;
    double value, tolerance;
  };
  for (const Case& c : {Case{"fault_dry_run", "dry_run", 0.0, 0.1}, Case{"fault_balance_piston_wear", "balance_piston_wear", 1.6, 0.1},
                        Case{"fault_crack", "rotor_crack", 0.7, 0.05}}) {
    const FrfData meas = read_frf_csv(data_file(std::string(c.dir) + "/frf.csv").string());
    const DiagnosisResult r = diagnose(plant, ref, meas);
    ASSERT_TRUE(r.detected) << c.dir;
    ASSERT_FALSE(r.faults.empty()) << c.dir;
    EXPECT_EQ(r.faults.front().name, c.first) << c.dir;
    EXPECT_NEAR(r.faults.front().value, c.value, c.tolerance) << c.dir;
    EXPECT_TRUE(r.explained) << c.dir;
    std::printf("%s: residual T/threshold %.3f, drift D %.1f (threshold %.1f); %s %s %.4f +- %.4f, chi2 %.0f -> %.0f, nrmse %.4f -> %.4f, "
                "%d model FRFs\n",
                c.dir, r.operating.residual_statistic / r.operating.residual_threshold, r.operating.drift_statistic,
                r.operating.drift_threshold, r.faults.front().name.c_str(), r.faults.front().location.c_str(), r.faults.front().value,
                r.faults.front().sd, r.chi2_before, r.chi2_after, r.nrmse_before, r.nrmse_after, r.evaluations);
    if (std::string(c.first) == "rotor_crack") {
      ASSERT_EQ(r.faults.front().hypothesis.elements.size(), 1u);
      EXPECT_LE(std::abs(r.faults.front().hypothesis.elements[0] - 8), 1);
    }
  }
  // The two shared runs left out are healthy.
  for (int i = 4; i <= 5; ++i) {
    const DiagnosisResult r =
        diagnose(plant, ref, read_frf_csv(data_file("reference_pump/frf_ref_" + std::to_string(i) + ".csv").string()));
    EXPECT_FALSE(r.detected) << "frf_ref_" << i << " p " << r.p_value;
    std::printf("frf_ref_%d: p %.3f (residual T/dof %.4f, drift D %.2f)\n", i, r.p_value,
                r.operating.residual_statistic / r.operating.residual_dof, r.operating.drift_statistic);
  }
}

// Runs estimated from time data state sigma with few degrees of freedom
// (`sigma_dof`, written by `ambdiag frf`): references and runs alike here,
// nu = 30. The residual test is then the scaled chi2 of diagnosis.h with
// the dof of both variances, kappa is tested against d1 F(d1, d2), and the
// rate stays at most alpha (binomial(200, 0.0253) for the residual alone: 5
// +- 2.2; measured 1, 4, 2 over three seeds; the slow test counts 1000).
TEST(OperatingReference, EstimatedSigmaKeepsTheFalseAlarmRate) {
  const PlantModel plant = reference_plant();
  const FrfData like = shared_like();
  const int nu = 30;
  std::mt19937_64 rng(16008);
  std::chi_squared_distribution<double> chi2(nu);
  auto estimated = [&](FrfData run) {
    for (auto& e : run.entries)
      for (double& sg : e.sigma) sg *= std::sqrt(chi2(rng) / nu);
    run.set_meta("sigma_dof", std::to_string(nu));
    return run;
  };
  const Operation op;
  DiagnosisOptions opt;
  opt.alpha = 0.05;
  opt.detect_only = true;
  int alarms = 0, residual = 0;
  for (int m = 0; m < 10; ++m) {
    std::vector<FrfData> refs;
    for (int i = 0; i < 3; ++i) refs.push_back(estimated(testing::healthy_run(plant, like, op, rng)));
    const OperatingReference ref = learn_operating_reference(plant, refs);
    for (int k = 0; k < 20; ++k) {
      const DiagnosisResult r = diagnose(plant, ref, estimated(testing::healthy_run(plant, like, op, rng)), opt);
      alarms += r.detected;
      residual += r.operating.residual_detected;
    }
  }
  std::printf("estimated sigma (nu %d): alarms %d of 200 (residual %d)\n", nu, alarms, residual);
  EXPECT_LE(alarms, 19);
  EXPECT_LE(residual, 12);
}

// A plant without fluid-seal links has no nuisance: the speed alone is
// followed, only the residual test runs (at alpha), and a crack is found.
TEST(OperatingReference, PlantWithoutSealLinksTestsTheResidualOnly) {
  PlantModel plant = reference_plant();
  std::erase_if(plant.links, [](const Link& l) { return l.kind == "seal" || l.kind == "balance_piston"; });
  const FrfData like = shared_like();
  std::mt19937_64 rng(16009);
  std::vector<FrfData> refs;
  for (double rpm : {2900.0, 2950.0, 3000.0}) refs.push_back(testing::simulate_run(plant, like, rpm, rng));
  const OperatingReference ref = operating_reference_from_json(operating_reference_to_json(learn_operating_reference(plant, refs)));
  EXPECT_TRUE(ref.nuisance_links.empty());
  DiagnosisOptions opt;
  opt.alpha = 1e-3;
  const DiagnosisResult healthy = diagnose(plant, ref, testing::simulate_run(plant, like, 3030.0, rng), opt);
  EXPECT_FALSE(healthy.detected) << healthy.p_value;
  EXPECT_EQ(healthy.operating.alpha_each, opt.alpha);
  const auto hyps = fault_hypotheses(plant);
  const FaultHypothesis* crack = nullptr;
  for (const auto& h : hyps)
    if (h.kind == FaultKind::rotor_crack && h.elements == std::vector<int>{8}) crack = &h;
  ASSERT_NE(crack, nullptr);
  const DiagnosisResult r = diagnose(plant, ref, testing::simulate_run(apply_fault(plant, *crack, 0.7), like, 2980.0, rng), opt);
  ASSERT_TRUE(r.detected);
  ASSERT_FALSE(r.faults.empty());
  EXPECT_EQ(r.faults.front().name, "rotor_crack");
  EXPECT_NEAR(r.faults.front().value, 0.7, 0.02);
}

// A measured run on another grid (half-line offsets, a narrower band): the
// references' b and its variance are interpolated; outside their range the
// run is refused.
TEST(OperatingReference, RunOnAnotherGridIsInterpolatedOrRefused) {
  const PlantModel plant = reference_plant();
  const FrfData like = shared_like();
  std::mt19937_64 rng(16006);
  std::vector<FrfData> refs;
  for (int i = 0; i < 3; ++i) refs.push_back(testing::simulate_run(plant, like, 2950.0, rng));
  const OperatingReference ref = learn_operating_reference(plant, refs);
  FrfData other = like;
  other.freq_hz.clear();
  for (double f = 1.5; f < 999.0; f += 2.0) other.freq_hz.push_back(f);
  for (auto& e : other.entries) {
    const FrfEntry* s = like.find(e.output, e.input);
    e.h.assign(other.freq_hz.size(), {0.0, 0.0});
    e.sigma.assign(other.freq_hz.size(), s->sigma.front());
    e.coh.clear();
  }
  const FrfData run = testing::simulate_run(plant, other, 2950.0, rng);
  DiagnosisOptions opt;
  opt.alpha = 1e-3;
  const DiagnosisResult r = diagnose(plant, ref, run, opt);
  EXPECT_FALSE(r.detected) << "p " << r.p_value << " T/dof " << r.operating.residual_statistic / r.operating.residual_dof;
  FrfData outside = run;
  outside.freq_hz.back() = 1200.0;
  try {
    diagnose(plant, ref, outside, opt);
    ADD_FAILURE() << "a line beyond the reference range was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("outside"), std::string::npos) << e.what();
  }
}

// Runs at other speeds drop other lines (the multisine estimator drops the
// line a speed harmonic falls on: at 1 Hz lines, 2950 rpm drops none, 3000
// rpm drops 50, 100, ...): a reference of such runs is learnt on the lines
// they all have, and a run with every line is tested against it. The old
// code refused it ("1000 lines, run 1 has 997"), so the server's reference
// job failed for every pump with speed spread (fleet test, issue 16).
TEST(OperatingReference, ReferenceRunsThatDroppedDifferentLinesAreLearntOnTheirCommonLines) {
  const PlantModel plant = reference_plant();
  const FrfData like = shared_like();
  std::mt19937_64 rng(16009);
  auto without = [](FrfData f, std::vector<double> drop_hz) {
    FrfData out = f;
    out.freq_hz.clear();
    for (auto& e : out.entries) e.h.clear(), e.sigma.clear(), e.coh.clear();
    for (size_t l = 0; l < f.freq_hz.size(); ++l) {
      bool dropped = false;
      for (double d : drop_hz) dropped = dropped || std::fabs(f.freq_hz[l] - d) < 1e-6;
      if (dropped) continue;
      out.freq_hz.push_back(f.freq_hz[l]);
      for (size_t e = 0; e < f.entries.size(); ++e) {
        out.entries[e].h.push_back(f.entries[e].h[l]);
        out.entries[e].sigma.push_back(f.entries[e].sigma[l]);
        if (!f.entries[e].coh.empty()) out.entries[e].coh.push_back(f.entries[e].coh[l]);
      }
    }
    return out;
  };
  const std::vector<std::vector<double>> dropped = {{50.0, 100.0, 150.0}, {49.0, 98.0}, {51.0, 102.0, 153.0}};
  std::vector<FrfData> refs;
  for (const auto& d : dropped) refs.push_back(without(testing::simulate_run(plant, like, 2950.0, rng), d));
  const OperatingReference ref = learn_operating_reference(plant, refs);
  EXPECT_EQ(ref.freq_hz.size(), like.freq_hz.size() - 8);
  DiagnosisOptions opt;
  opt.alpha = 1e-3;
  const DiagnosisResult r = diagnose(plant, ref, testing::simulate_run(plant, like, 2950.0, rng), opt);
  EXPECT_FALSE(r.detected) << "p " << r.p_value;
  EXPECT_EQ(r.operating.residual_dof, 2 * static_cast<double>(like.freq_hz.size() * like.entries.size()) - 2)
      << "the run is tested on all its lines";
  // More than a few dropped lines is another grid, not dropped lines.
  std::vector<double> many;
  for (int i = 0; i < 150; ++i) many.push_back(5.0 + 3.0 * i);
  refs[1] = without(refs[1], many);
  try {
    learn_operating_reference(plant, refs);
    ADD_FAILURE() << "a run lacking 15 % of the lines was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("in every reference run"), std::string::npos) << e.what();
  }
}

// A big crack (EI x 0.5) on the fleet tests' second machine (longer,
// thicker shaft, tests/support/second_pump.h): the screening's linearised
// estimate ranks the cracked element only 4th to 6th behind its neighbours
// (elements 3, 11, 13, 14 below, and the fleet test's crack at element 9,
// which lost to the hub joint, shaft_nut_loosening, at 3 refined elements:
// 8 of 21 EI-0.5 cracks misplaced with 3, 1 with 5, none with 6, for 10 %
// more model evaluations). The default refines 6.
TEST(OperatingReference, BigCrackOnTheSecondMachineIsPlacedAtItsElement) {
  const PlantModel plant = testing::second_pump(reference_plant());
  const FrfData like = shared_like();
  std::mt19937_64 rng(16010);
  Operation op;
  op.nominal_rpm = plant.speed_rpm;
  std::vector<FrfData> refs;
  for (int i = 0; i < 3; ++i) refs.push_back(testing::healthy_run(plant, like, op, rng));
  const OperatingReference ref = learn_operating_reference(plant, refs);
  const auto hyps = fault_hypotheses(plant);
  for (int element : {3, 9, 11, 13, 14}) {
    const FaultHypothesis* crack = nullptr;
    for (const auto& h : hyps)
      if (h.kind == FaultKind::rotor_crack && h.elements == std::vector<int>{element}) crack = &h;
    ASSERT_NE(crack, nullptr);
    DiagnosisOptions opt;
    opt.alpha = kRecommendedAlphaPerRun;
    const DiagnosisResult r = diagnose(plant, ref, testing::healthy_run(apply_fault(plant, *crack, 0.5), like, op, rng), opt);
    ASSERT_TRUE(r.detected) << element;
    ASSERT_FALSE(r.faults.empty());
    const FaultEstimate& f = r.faults.front();
    EXPECT_EQ(f.name, "rotor_crack") << element;
    EXPECT_EQ(f.hypothesis.elements, std::vector<int>{element}) << f.name << " at " << f.hypothesis.elements.front();
    // The interval holds the truth: the noise is the model's own (1 % of
    // the RMS) and the crack's change is large, so a few times its sd.
    EXPECT_LE(f.ci_lo, 0.5) << element;
    EXPECT_GE(f.ci_hi, 0.5) << element;
  }
}

// A sensor at gain 0.8 on a run with seal drift at another speed: the gain
// is fitted jointly with the drift. Fitted on the prediction with the drift
// fitted to the faulty run (which takes up part of the gain's change), it
// came out 0.8012 +- 0.0003 in the fleet test (tests/integration), the
// interval missing the truth by 4 sd.
TEST(OperatingReference, SensorGainUnderSealDriftIsFittedWithTheDrift) {
  const PlantModel plant = reference_plant();
  const FrfData like = shared_like();
  std::mt19937_64 rng(16011);
  const Operation op;
  std::vector<FrfData> refs;
  for (int i = 0; i < 3; ++i) refs.push_back(testing::healthy_run(plant, like, op, rng));
  const OperatingReference ref = learn_operating_reference(plant, refs);
  int held = 0;
  const int n = 6;
  for (int i = 0; i < n; ++i) {
    FrfData run = testing::simulate_run(testing::drifted(plant, SealDrift{0.03 * (i % 3 - 1), {}}), like, 2950.0 * (1.0 + 0.01 * (i - 2)), rng);
    for (auto& e : run.entries)
      if (e.output == "xAx")
        for (auto& h : e.h) h *= 0.8;
    DiagnosisOptions opt;
    opt.alpha = kRecommendedAlphaPerRun;
    const DiagnosisResult r = diagnose(plant, ref, run, opt);
    ASSERT_TRUE(r.detected);
    const FaultEstimate& f = r.faults.front();
    EXPECT_EQ(f.name, "sensor_fault");
    EXPECT_EQ(f.hypothesis.channel, "xAx");
    std::printf("sensor gain 0.8, common drift %+.0f %%: %.5f [%.5f, %.5f]\n", 3.0 * (i % 3 - 1), f.value, f.ci_lo, f.ci_hi);
    held += f.ci_lo <= 0.8 && 0.8 <= f.ci_hi ? 1 : 0;
  }
  // 95 % intervals: 6 of 6 hold the truth with probability 0.74, 5 or more
  // 0.97; fewer is a biased estimate or a too narrow interval.
  EXPECT_GE(held, n - 1);
}

TEST(OperatingReference, JsonRoundTripKeepsTheResult) {
  const PlantModel plant = reference_plant();
  const OperatingReference ref = learn_operating_reference(plant, shared_references(3));
  const std::string text = operating_reference_to_json(ref);
  const OperatingReference back = operating_reference_from_json(text);
  EXPECT_EQ(operating_reference_to_json(back), text);
  EXPECT_EQ(back.nuisance_links, ref.nuisance_links);
  EXPECT_EQ(back.runs.size(), 3u);
  EXPECT_EQ(back.entries.size(), ref.entries.size());
  EXPECT_EQ(back.entries[3].bias[100], ref.entries[3].bias[100]);
  const FrfData meas = read_frf_csv(data_file("reference_pump/frf_ref_4.csv").string());
  DiagnosisOptions opt;
  opt.detect_only = true;
  EXPECT_EQ(diagnose(plant, ref, meas, opt).statistic, diagnose(plant, back, meas, opt).statistic);
}

TEST(OperatingReference, BadDocumentsAreRefusedNamingTheField) {
  const PlantModel plant = reference_plant();
  const std::string good = operating_reference_to_json(learn_operating_reference(plant, shared_references(2)));
  auto refused_naming = [&](const std::string& text, const std::string& name) {
    try {
      operating_reference_from_json(text);
      ADD_FAILURE() << "accepted a document with a bad " << name;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  };
  auto replaced = [&](const std::string& from, const std::string& to) {
    std::string s = good;
    const auto at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, from.size(), to);
  };
  refused_naming("{not json", "invalid JSON");
  refused_naming("[]", "must be an object");
  refused_naming(replaced("\"format\":\"ambdiag.operating_reference/1\"", "\"format\":\"x\""), "format");
  refused_naming(replaced("\"kappa\":", "\"kappa_\":"), "entries[0].kappa");
  refused_naming(replaced("\"speed_rpm\":", "\"speed_rpm\":\"fast\",\"x\":"), "runs[0].speed_rpm");
  refused_naming(replaced("\"common_sd\":", "\"common_sd\":-1,\"y\":"), "common_sd");
  EXPECT_NO_THROW(operating_reference_from_json(good));
}

TEST(OperatingReference, RefusesRunsThatCannotBeAReference) {
  const PlantModel plant = reference_plant();
  std::vector<FrfData> runs = shared_references(3);
  auto refused_naming = [&](const std::vector<FrfData>& rs, const std::string& name) {
    try {
      learn_operating_reference(plant, rs);
      ADD_FAILURE() << "accepted: " << name;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  };
  refused_naming({runs[0]}, "at least 2");
  auto bad = runs;
  bad[2].freq_hz[10] += 0.25;
  refused_naming(bad, "reference run 3");
  bad = runs;
  bad[1].entries[4].sigma.clear();
  refused_naming(bad, "reference run 2");
  bad = runs;
  bad[1].entries.pop_back();
  refused_naming(bad, "reference run 2");
  PlantModel fewer = plant;
  fewer.sensors.pop_back();
  try {
    learn_operating_reference(fewer, runs);
    ADD_FAILURE() << "a model without a measured channel was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("reference run 1"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ambdiag
