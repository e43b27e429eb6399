#include "ambdiag/algorithms/estimation/frf_estimation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <numbers>
#include <random>
#include <string>

#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/core/error.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"
#include "ambdiag/core/run_recording.h"
#include "test_support.h"

namespace ambdiag {
namespace {

// |H_est - H_truth|^2 / (sigma_est^2 + sigma_truth^2) over the common lines:
// about 1 in the mean when the estimate is unbiased and its sigma right.
struct NoiseStats {
  double mean = 0.0;   // over all lines and entries
  double worst = 0.0;  // the entry mean farthest from 1 (in log)
  std::string worst_entry;
  long lines = 0;
};

NoiseStats compare(const FrfData& est, const FrfData& truth) {
  NoiseStats st;
  double sum = 0.0;
  long n = 0;
  for (const auto& e : est.entries) {
    const FrfEntry* t = truth.find(e.output, e.input);
    EXPECT_NE(t, nullptr) << e.output << "/" << e.input;
    if (!t) continue;
    EXPECT_EQ(e.sigma.size(), e.h.size());
    double es = 0.0;
    long en = 0;
    size_t j = 0;
    for (size_t l = 0; l < est.freq_hz.size(); ++l) {
      const double f = est.freq_hz[l];
      while (j < truth.freq_hz.size() && truth.freq_hz[j] < f * (1 - 1e-9)) ++j;
      if (j == truth.freq_hz.size() || std::abs(truth.freq_hz[j] - f) > 1e-9 * f) continue;
      const double ts = t->sigma.empty() ? 0.0 : t->sigma[j];
      es += std::norm(e.h[l] - t->h[j]) / (e.sigma[l] * e.sigma[l] + ts * ts);
      ++en;
    }
    if (en == 0) continue;
    sum += es;
    n += en;
    st.lines = en;
    const double m = es / static_cast<double>(en);
    if (st.worst_entry.empty() || std::abs(std::log(m)) > std::abs(std::log(st.worst))) {
      st.worst = m;
      st.worst_entry = e.output + "/" + e.input;
    }
  }
  st.mean = n > 0 ? sum / static_cast<double>(n) : 0.0;
  return st;
}

void report(const char* what, const NoiseStats& s) {
  std::printf("%s: mean |dH|^2/sigma^2 %.3f over %ld lines, worst entry %s %.3f\n", what, s.mean, s.lines,
              s.worst_entry.c_str(), s.worst);
}

FrfData model_frf(const FrfData& at) {
  const PlantModel plant = read_plant_file(testing::data_file("reference_pump/plant.json"));
  return synthesize_frf(plant, 2950.0, at.freq_hz);
}

TEST(FrfEstimation, MultisineReferenceRunIsUnbiasedWithinItsReportedNoise) {
  const RunRecording run = read_run(testing::data_file("reference_pump/run_ref_1").string());
  const FrfEstimate est = estimate_frf(run);
  EXPECT_EQ(est.method, "multisine");
  EXPECT_TRUE(est.warnings.empty()) << est.warnings.front();
  ASSERT_EQ(est.frf.entries.size(), 25u);
  EXPECT_EQ(est.frf.freq_hz.size(), 1000u);
  EXPECT_EQ(est.frf.quantity, FrfQuantity::compliance);
  EXPECT_EQ(est.frf.unit, "m/N");
  // sigma^2 pools the period-to-period covariance of every segment:
  // sum (periods - settle - 1) complex degrees of freedom, twice as many
  // real; the synchronous fit takes some mostly next to h x speed, so the
  // median line keeps them all but a fraction (the figure is rounded down).
  long dof = 0;
  for (const auto& seg : run.excitation->segments) dof += seg.periods - seg.settle_periods - 1;
  ASSERT_TRUE(est.frf.meta("sigma_dof"));
  const long stated = std::stol(*est.frf.meta("sigma_dof"));
  EXPECT_LE(stated, 2 * dof);
  EXPECT_GE(stated, 2 * dof - 1);
  const NoiseStats s = compare(est.frf, model_frf(est.frf));
  report("run_ref_1", s);
  EXPECT_GT(s.mean, 0.8);
  EXPECT_LT(s.mean, 1.25);
  EXPECT_GT(s.worst, 0.6) << s.worst_entry;
  EXPECT_LT(s.worst, 1.6) << s.worst_entry;
}

TEST(FrfEstimation, StepsineRunReproducesTruthWithinItsReportedNoise) {
  const RunRecording run = read_run(testing::data_file("reference_pump/run_stepsine").string());
  const FrfEstimate est = estimate_frf(run);
  EXPECT_EQ(est.method, "stepsine");
  EXPECT_TRUE(est.warnings.empty()) << est.warnings.front();
  EXPECT_EQ(est.frf.freq_hz.size(), 60u);
  const FrfData truth =
      read_frf_csv(testing::data_file("reference_pump/run_stepsine/frf_truth.csv").string());
  const NoiseStats s = compare(est.frf, truth);
  report("run_stepsine", s);
  EXPECT_GT(s.mean, 0.6);
  EXPECT_LT(s.mean, 1.6);
}

TEST(FrfEstimation, FaultRunsAgreeWithTheirFrfFilesWithinBothNoises) {
  for (const char* c : {"fault_dry_run", "fault_crack"}) {
    const RunRecording run = read_run(testing::data_file(std::string(c) + "/run").string());
    const FrfEstimate est = estimate_frf(run);
    const FrfData truth = read_frf_csv(testing::data_file(std::string(c) + "/frf.csv").string());
    const NoiseStats s = compare(est.frf, truth);
    report(c, s);
    EXPECT_GT(s.mean, 0.8) << c;
    EXPECT_LT(s.mean, 1.25) << c;
  }
}

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

TEST(FrfEstimation, AmrotorChirpGivesCoherentAccelerancesPeakingAtTheRigsModes) {
  const RunRecording run = read_run(testing::data_file("external/amrotor_mlps_sweep").string());
  const FrfEstimate est = estimate_frf(run);
  EXPECT_EQ(est.method, "gated");
  EXPECT_EQ(est.frf.quantity, FrfQuantity::accelerance);
  EXPECT_EQ(est.frf.unit, "(m/s^2)/V");
  ASSERT_EQ(est.frf.entries.size(), 8u);
  EXPECT_EQ(est.frf.entries[0].output, "a1");
  EXPECT_EQ(est.frf.entries[0].input, "u");
  const auto& f = est.frf.freq_hz;
  EXPECT_GT(f.front(), 0.0);
  EXPECT_LE(f.back(), 500.0);
  EXPECT_LT(f.front(), 8.0);
  EXPECT_GT(f.back(), 480.0);
  // Prominent maxima of sum |H|^2 over the accelerometers: the largest
  // within +-4 Hz and 5 times the smallest within +-12 Hz.
  std::vector<double> p(f.size(), 0.0);
  for (const auto& e : est.frf.entries)
    for (size_t l = 0; l < f.size(); ++l) p[l] += std::norm(e.h[l]);
  std::vector<double> peaks;
  for (size_t l = 0; l < f.size(); ++l) {
    double hi = 0.0, lo = p[l];
    for (size_t j = 0; j < f.size(); ++j) {
      if (std::abs(f[j] - f[l]) <= 4.0) hi = std::max(hi, p[j]);
      if (std::abs(f[j] - f[l]) <= 12.0) lo = std::min(lo, p[j]);
    }
    if (p[l] == hi && p[l] > 5.0 * lo) peaks.push_back(f[l]);
  }
  std::string seen;
  for (double x : peaks) seen += " " + std::to_string(x);
  std::printf("amrotor peaks:%s\n", seen.c_str());
  // The rig's authors' natural frequencies, read by eye: most must be peaks.
  int found = 0;
  for (double target : {16.0, 51.0, 59.0, 100.0, 162.0, 204.0, 212.0}) {
    found += std::any_of(peaks.begin(), peaks.end(), [&](double x) { return std::abs(x - target) <= 2.5; });
  }
  EXPECT_GE(found, 5) << seen;
  // Coherence: high over the band, and at the peaks.
  std::vector<double> coh, coh_peaks;
  for (const auto& e : est.frf.entries) {
    ASSERT_EQ(e.coh.size(), f.size());
    for (size_t l = 0; l < f.size(); ++l) {
      if (f[l] < 5 || f[l] > 500) continue;
      coh.push_back(e.coh[l]);
      if (std::find(peaks.begin(), peaks.end(), f[l]) != peaks.end()) coh_peaks.push_back(e.coh[l]);
    }
  }
  std::printf("amrotor coherence 5-500 Hz: median %.3f, at the peaks median %.3f\n", median(coh),
              median(coh_peaks));
  EXPECT_GT(median(coh), 0.8);
  EXPECT_GT(median(coh_peaks), 0.9);
}

// A closed loop with a known plant: references r, measured forces
// f = r - K x_measured (the displacement noise is fed back), x = G f.
struct ClosedLoop {
  RunRecording run;
  FrfData truth_at(const std::vector<double>& freq_hz) const;
  double fs = 1000.0, rho = 0.97;
  double f0[2][2] = {{80.0, 150.0}, {150.0, 230.0}}, b[2][2] = {{1e-6, 3e-7}, {3e-7, 8e-7}};
};

FrfData ClosedLoop::truth_at(const std::vector<double>& freq_hz) const {
  FrfData t;
  t.freq_hz = freq_hz;
  for (int i = 0; i < 2; ++i) {
    for (int j = 0; j < 2; ++j) {
      FrfEntry e;
      e.output = "x" + std::to_string(i + 1);
      e.input = "f" + std::to_string(j + 1);
      const double th = 2 * std::numbers::pi * f0[i][j] / fs;
      for (double fh : t.freq_hz) {
        const std::complex<double> z1 = std::polar(1.0, -2 * std::numbers::pi * fh / fs);
        e.h.push_back(b[i][j] * z1 / (1.0 - 2 * rho * std::cos(th) * z1 + rho * rho * z1 * z1));
      }
      t.entries.push_back(e);
    }
  }
  return t;
}

// Two-input two-output plant of lightly damped discrete resonators
// G_ij(z) = b_ij z^-1 / (1 - 2 rho cos(theta_ij) z^-1 + rho^2 z^-2).
// Chirp: one sweep per input in turn, each over its own segment; the first
// lasts `first_sweep` frames (default: half the run), the second the rest.
ClosedLoop simulate_closed_loop(ExcitationType type, long frames, double noise_x, double noise_f,
                                long first_sweep = 0) {
  ClosedLoop c;
  const double fs = c.fs, rho = c.rho;
  const auto& f0 = c.f0;
  const auto& b = c.b;
  const double k_ctrl = 2e5;  // N/m, proportional feedback
  RunRecording& run = c.run;
  run.pump_id = "SIM";
  run.run_id = "SIM/closed-loop";
  run.kind = "identification";
  run.sample_rate_hz = fs;
  const auto add = [&](const std::string& name, ChannelRole role, const std::string& unit,
                       const std::string& in) {
    Channel ch;
    ch.name = name;
    ch.role = role;
    ch.role_text = to_string(role);
    ch.unit = unit;
    ch.input = in;
    run.channels.push_back(ch);
  };
  add("r1", ChannelRole::reference, "N", "f1");
  add("r2", ChannelRole::reference, "N", "f2");
  add("f1", ChannelRole::force, "N", "");
  add("f2", ChannelRole::force, "N", "");
  add("x1", ChannelRole::displacement, "m", "");
  add("x2", ChannelRole::displacement, "m", "");
  Excitation ex;
  ex.type = type;
  ex.f_min_hz = 0.0;
  ex.f_max_hz = fs / 2;
  // Random: both references at once; chirp: one sweep per input, in turn.
  if (type == ExcitationType::chirp) ex.f_max_hz = 0.45 * fs;
  const long len0 = first_sweep > 0 ? first_sweep : frames / 2;
  const auto add_segment = [&](long start, long length) {
    ExcitationSegment seg;
    seg.start = start;
    seg.length = length;
    ex.segments.push_back(seg);
  };
  if (type == ExcitationType::chirp) {
    add_segment(0, len0);
    add_segment(len0, frames - len0);
  } else {
    add_segment(0, frames);
  }
  run.excitation = ex;

  std::mt19937_64 rng(12345);
  std::normal_distribution<double> gauss(0.0, 1.0);
  double y[2][2][2] = {};  // y[i][j][lag]: state of G_ij
  double f_prev[2] = {0.0, 0.0};
  for (long n = 0; n < frames; ++n) {
    double x[2] = {0.0, 0.0};
    for (int i = 0; i < 2; ++i) {
      for (int j = 0; j < 2; ++j) {
        const double th = 2 * std::numbers::pi * f0[i][j] / fs;
        const double v = 2 * rho * std::cos(th) * y[i][j][0] - rho * rho * y[i][j][1] + b[i][j] * f_prev[j];
        y[i][j][1] = y[i][j][0];
        y[i][j][0] = v;
        x[i] += v;
      }
    }
    double r[2], f[2], xm[2];
    for (int i = 0; i < 2; ++i) {
      if (type == ExcitationType::chirp) {
        const long begin = i == 0 ? 0 : len0, len = i == 0 ? len0 : frames - len0, k = n - begin;
        const double t = static_cast<double>(k) / fs, rate = 0.45 * fs / (static_cast<double>(len) / fs);
        r[i] = (k >= 0 && k < len) ? 30.0 * std::sin(std::numbers::pi * rate * t * t) : 0.0;
      } else {
        r[i] = 10.0 * gauss(rng);
      }
      xm[i] = x[i] + noise_x * gauss(rng);
      f[i] = r[i] - k_ctrl * xm[i];
      f_prev[i] = f[i];
    }
    for (double v : {r[0], r[1], f[0] + noise_f * gauss(rng), f[1] + noise_f * gauss(rng), xm[0], xm[1]}) {
      run.samples.push_back(static_cast<float>(v));
    }
  }
  return c;
}

TEST(FrfEstimation, WelchWithReferencesIsUnbiasedInClosedLoopWhereH1IsNot) {
  const ClosedLoop c = simulate_closed_loop(ExcitationType::random, 1 << 16, 1e-5, 0.5);
  FrfEstimationOptions opt;
  // Windows much longer than the impulse response (decay to 1 % in 150
  // samples): with 256-sample windows the truncation (leakage) bias exceeds
  // the noise.
  opt.nfft = 2048;
  const FrfEstimate iv = estimate_frf(c.run, opt);
  EXPECT_EQ(iv.method, "welch-ref");
  EXPECT_TRUE(iv.warnings.empty()) << iv.warnings.front();
  EXPECT_EQ(iv.averages, 63);
  const NoiseStats s = compare(iv.frf, c.truth_at(iv.frf.freq_hz));
  report("closed loop, welch-ref", s);
  EXPECT_GT(s.mean, 0.85);
  EXPECT_LT(s.mean, 1.2);
  EXPECT_GT(s.worst, 0.75) << s.worst_entry;
  EXPECT_LT(s.worst, 1.3) << s.worst_entry;

  opt.method = NonperiodicMethod::h1;
  const FrfEstimate h1 = estimate_frf(c.run, opt);
  EXPECT_EQ(h1.method, "welch-h1");
  const NoiseStats b = compare(h1.frf, c.truth_at(h1.frf.freq_hz));
  report("closed loop, welch-h1 (biased by the feedback)", b);
  EXPECT_GT(b.mean, 1.8);
}

// The closed-loop estimate agrees with the plant within its reported noise:
// mean |dH|^2 / sigma^2 over all entries near 1, and every entry's mean too.
void expect_within_noise(const ClosedLoop& c, const FrfEstimate& est, const char* what) {
  const NoiseStats s = compare(est.frf, c.truth_at(est.frf.freq_hz));
  report(what, s);
  EXPECT_GT(s.mean, 0.8) << what;
  EXPECT_LT(s.mean, 1.25) << what;
  EXPECT_GT(s.worst, 0.7) << what << ": " << s.worst_entry;
  EXPECT_LT(s.worst, 1.4) << what << ": " << s.worst_entry;
}

TEST(FrfEstimation, GatedSweepsOnePerInputAreUnbiasedInClosedLoop) {
  const ClosedLoop c = simulate_closed_loop(ExcitationType::chirp, 1 << 16, 1e-5, 0.5);
  const FrfEstimate est = estimate_frf(c.run);
  EXPECT_EQ(est.method, "gated");
  for (const auto& w : est.warnings) ADD_FAILURE() << w;
  expect_within_noise(c, est, "closed loop, two sweeps, gated");
}

// Gating needs sweeps of one length; a run whose sweeps last differently
// (here 36 s and 29.5 s) falls back to Welch averaging with the
// references, says so, and stays unbiased within its reported noise.
TEST(FrfEstimation, SweepsOfDifferentLengthsFallBackToWelchWithAWarning) {
  const ClosedLoop c = simulate_closed_loop(ExcitationType::chirp, 1 << 16, 1e-5, 0.5, 36000);
  FrfEstimationOptions opt;
  opt.nfft = 2048;  // as in the random-excitation test: windows far longer than the impulse response
  const FrfEstimate est = estimate_frf(c.run, opt);
  EXPECT_EQ(est.method, "welch-ref");
  ASSERT_FALSE(est.warnings.empty());
  EXPECT_NE(est.warnings.front().find("segments of different lengths: Welch averaging instead of gating"),
            std::string::npos)
      << est.warnings.front();
  expect_within_noise(c, est, "closed loop, two sweeps of different lengths, Welch fallback");
}

// A segment that stops before its sweep does leaves the top of that
// input's band without excitation: those lines are dropped with a warning
// naming the reference (kept, their sigma was 2-3 x too small: mean
// |dH|^2/sigma^2 4-9 there), and the rest stays unbiased.
TEST(FrfEstimation, LinesOneInputDoesNotExciteAreDroppedNamingIt) {
  ClosedLoop c = simulate_closed_loop(ExcitationType::chirp, 1 << 16, 1e-5, 0.5);
  c.run.excitation->segments.back().length -= 4096;  // the last 12 % of the second sweep left out
  FrfEstimationOptions opt;
  opt.nfft = 2048;
  const FrfEstimate est = estimate_frf(c.run, opt);
  EXPECT_EQ(est.method, "welch-ref");
  bool named = false;
  for (const auto& w : est.warnings) named = named || w.find("instrument r2 has less than 1 %") != std::string::npos;
  EXPECT_TRUE(named) << ::testing::PrintToString(est.warnings);
  // The sweep reaches 0.45 fs = 450 Hz; 12 % of it is left out: above
  // about 400 Hz there is no line.
  ASSERT_FALSE(est.frf.freq_hz.empty());
  EXPECT_LT(est.frf.freq_hz.back(), 405.0);
  EXPECT_GT(est.frf.freq_hz.back(), 350.0);
  expect_within_noise(c, est, "closed loop, second sweep cut short, Welch");
}

TEST(FrfEstimation, HvAgreesWithTheReferenceEstimateAtHighSignalToNoise) {
  const ClosedLoop c = simulate_closed_loop(ExcitationType::random, 1 << 15, 1e-8, 0.01);
  FrfEstimationOptions opt;
  opt.nfft = 2048;
  opt.method = NonperiodicMethod::hv;
  const FrfEstimate hv = estimate_frf(c.run, opt);
  EXPECT_EQ(hv.method, "welch-hv");
  const FrfData truth = c.truth_at(hv.frf.freq_hz);
  std::vector<double> rel;
  for (size_t k = 0; k < hv.frf.entries.size(); ++k) {
    for (size_t l = 0; l < truth.freq_hz.size(); ++l) {
      rel.push_back(std::abs(hv.frf.entries[k].h[l] - truth.entries[k].h[l]) /
                    std::abs(truth.entries[k].h[l]));
    }
  }
  std::printf("closed loop, welch-hv: median relative error %.4f\n", median(rel));
  EXPECT_LT(median(rel), 0.02);
}

// A sweep 0..450 Hz in 16 s through two lightly damped resonators (80 and
// 230 Hz, impulse response decaying to 1 % in about 1 s), white output noise.
struct Sweep {
  RunRecording run;
  double fs = 1000.0, rho = 0.995, f0[2] = {80.0, 230.0};
  std::complex<double> h(double f_hz) const {
    const std::complex<double> z1 = std::polar(1.0, -2 * std::numbers::pi * f_hz / fs);
    std::complex<double> sum = 0.0;
    for (double f : f0)
      sum += z1 / (1.0 - 2 * rho * std::cos(2 * std::numbers::pi * f / fs) * z1 + rho * rho * z1 * z1);
    return sum;
  }
};

Sweep simulate_sweep() {
  Sweep sw;
  const long n = 16384;
  RunRecording& run = sw.run;
  run.pump_id = "SIM";
  run.run_id = "SIM/sweep";
  run.kind = "identification";
  run.sample_rate_hz = sw.fs;
  Channel u;
  u.name = "u";
  u.role = ChannelRole::reference;
  u.unit = "V";
  u.input = "u";
  Channel y;
  y.name = "y";
  y.role = ChannelRole::acceleration;
  y.unit = "m/s^2";
  run.channels = {u, y};
  Excitation ex;
  ex.type = ExcitationType::chirp;
  ex.f_max_hz = 450;
  ExcitationSegment seg;
  seg.length = n;
  ex.segments.push_back(seg);
  run.excitation = ex;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> gauss(0.0, 1.0);
  double state[2][2] = {}, u_prev = 0.0;
  const double rate = 450.0 / (static_cast<double>(n) / sw.fs);  // Hz/s
  for (long k = 0; k < n; ++k) {
    double yv = 0.0;
    for (int m = 0; m < 2; ++m) {
      const double c = 2 * sw.rho * std::cos(2 * std::numbers::pi * sw.f0[m] / sw.fs);
      const double v = c * state[m][0] - sw.rho * sw.rho * state[m][1] + u_prev;
      state[m][1] = state[m][0];
      state[m][0] = v;
      yv += v;
    }
    const double t = static_cast<double>(k) / sw.fs;
    u_prev = std::sin(std::numbers::pi * rate * t * t);
    run.samples.push_back(static_cast<float>(u_prev));
    run.samples.push_back(static_cast<float>(yv + 0.2 * gauss(rng)));
  }
  return sw;
}

TEST(FrfEstimation, SweepGatedAndLocalPolynomialEstimatesAreUnbiasedWithinTheirNoise) {
  const Sweep sw = simulate_sweep();
  for (NonperiodicMethod m : {NonperiodicMethod::automatic, NonperiodicMethod::lpm}) {
    FrfEstimationOptions opt;
    opt.method = m;
    const FrfEstimate est = estimate_frf(sw.run, opt);
    EXPECT_EQ(est.method, m == NonperiodicMethod::lpm ? "lpm" : "gated");
    FrfData truth;
    truth.freq_hz = est.frf.freq_hz;
    truth.entries.push_back({"y", "u", {}, {}, {}});
    for (double f : truth.freq_hz) truth.entries[0].h.push_back(sw.h(f));
    const NoiseStats s = compare(est.frf, truth);
    double near = 0.0;  // within 3 Hz of the resonances, where window truncation would bias
    long n = 0;
    for (size_t l = 0; l < truth.freq_hz.size(); ++l) {
      if (std::abs(truth.freq_hz[l] - 80) > 3 && std::abs(truth.freq_hz[l] - 230) > 3) continue;
      near += std::norm(est.frf.entries[0].h[l] - truth.entries[0].h[l]) /
              std::pow(est.frf.entries[0].sigma[l], 2);
      ++n;
    }
    near /= static_cast<double>(n);
    std::printf("sweep, %s: mean |dH|^2/sigma^2 %.3f over %ld lines, %.3f near the resonances\n",
                est.method.c_str(), s.mean, s.lines, near);
    EXPECT_GT(s.mean, 0.85) << est.method;
    EXPECT_LT(s.mean, 1.25) << est.method;
    EXPECT_GT(near, 0.4) << est.method;
    EXPECT_LT(near, 1.5) << est.method;
  }
}

// Bad runs, made from copies of real ones.
const RunRecording& reference_run() {
  static const RunRecording run = read_run(testing::data_file("reference_pump/run_ref_1").string());
  return run;
}

const RunRecording& stepsine_run() {
  static const RunRecording run = read_run(testing::data_file("reference_pump/run_stepsine").string());
  return run;
}

template <typename F>
void edit_channel(RunRecording& run, const std::string& name, int64_t begin, int64_t end, F f) {
  const int c = run.channel_index(name);
  ASSERT_GE(c, 0) << name;
  for (int64_t t = begin; t < end; ++t) {
    float& v = run.samples[static_cast<size_t>(t) * run.channels.size() + static_cast<size_t>(c)];
    v = f(v);
  }
}

std::string error_of(const RunRecording& run) {
  try {
    estimate_frf(run);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(FrfEstimationBadRuns, ClippedChannelIsRefusedByName) {
  RunRecording run = reference_run();
  const int c = run.channel_index("xBx");
  float top = 0;
  for (int64_t t = 0; t < run.frame_count(); ++t) top = std::max(top, std::abs(run.at(t, c)));
  const float lim = 0.7f * top;
  edit_channel(run, "xBx", 0, run.frame_count(), [&](float v) { return std::clamp(v, -lim, lim); });
  const std::string e = error_of(run);
  EXPECT_NE(e.find("channel xBx: clipped"), std::string::npos) << e;
}

TEST(FrfEstimationBadRuns, DeadSensorIsRefusedByName) {
  RunRecording run = reference_run();
  edit_channel(run, "fAy", 0, run.frame_count(), [](float) { return 0.0f; });
  const std::string e = error_of(run);
  EXPECT_NE(e.find("channel fAy: constant"), std::string::npos) << e;
}

TEST(FrfEstimationBadRuns, ZeroReferenceIsRefusedNamingTheChannel) {
  RunRecording run = reference_run();
  edit_channel(run, "rZ", 0, run.frame_count(), [](float) { return 0.0f; });
  const std::string e = error_of(run);
  EXPECT_NE(e.find("reference channel rZ (input fZ) is zero"), std::string::npos) << e;
}

TEST(FrfEstimationBadRuns, TooFewSegmentsForTheInputsAreRefused) {
  RunRecording run = reference_run();
  run.excitation->segments.pop_back();
  const std::string e = error_of(run);
  EXPECT_NE(e.find("4 usable segment(s) for 5 inputs"), std::string::npos) << e;
}

TEST(FrfEstimationBadRuns, RepeatedPatternsLeaveNoSolvableLine) {
  // Segment 1 a copy of segment 0: four independent patterns for five inputs.
  RunRecording run = reference_run();
  const auto& segs = run.excitation->segments;
  const size_t frame = run.channels.size();
  std::copy_n(run.samples.begin() + static_cast<long>(segs[0].start * static_cast<int64_t>(frame)),
              segs[0].periods * run.excitation->period_samples * static_cast<int64_t>(frame),
              run.samples.begin() + static_cast<long>(segs[1].start * static_cast<int64_t>(frame)));
  const std::string e = error_of(run);
  EXPECT_NE(e.find("no line could be estimated"), std::string::npos) << e;
  EXPECT_NE(e.find("not linearly independent"), std::string::npos) << e;
}

TEST(FrfEstimationBadRuns, SinglePeriodSegmentsGiveHWithoutSigmaAndAWarning) {
  RunRecording run = reference_run();
  for (auto& s : run.excitation->segments) s.settle_periods = s.periods - 1;
  const FrfEstimate est = estimate_frf(run);
  ASSERT_EQ(est.warnings.size(), 1u);
  EXPECT_NE(est.warnings[0].find("no period-to-period variance"), std::string::npos) << est.warnings[0];
  EXPECT_TRUE(est.frf.entries[0].sigma.empty());
  EXPECT_TRUE(est.frf.entries[0].coh.empty());
  EXPECT_TRUE(est.frf.meta("warning_1").has_value());
  // One segment with a single period: the pooled covariance still gives sigma.
  run = reference_run();
  run.excitation->segments[2].settle_periods = run.excitation->segments[2].periods - 1;
  const FrfEstimate pooled = estimate_frf(run);
  EXPECT_TRUE(pooled.warnings.empty());
  EXPECT_FALSE(pooled.frf.entries[0].sigma.empty());
}

TEST(FrfEstimationBadRuns, StepWithZeroReferenceIsDroppedWithAWarning) {
  RunRecording run = stepsine_run();
  size_t k = 0;
  while (!(run.excitation->segments[k].input == "fBy" && run.excitation->segments[k].freq_hz > 100)) ++k;
  const auto& seg = run.excitation->segments[k];
  edit_channel(run, "rBy", seg.start, seg.start + seg.length, [](float) { return 0.0f; });
  const FrfEstimate est = estimate_frf(run);
  EXPECT_EQ(est.frf.freq_hz.size(), 59u);
  EXPECT_EQ(est.lines_dropped, 1);
  ASSERT_EQ(est.warnings.size(), 2u);
  EXPECT_NE(est.warnings[0].find("reference is zero: segment " + std::to_string(k)), std::string::npos)
      << est.warnings[0];
  EXPECT_NE(est.warnings[1].find("dropped: no usable segment drives fBy"), std::string::npos)
      << est.warnings[1];
}

TEST(FrfEstimationBadRuns, MonitoringRunHasNoFrf) {
  RunRecording run = reference_run();
  run.kind = "monitoring";
  run.excitation.reset();
  EXPECT_NE(error_of(run).find("excitation: none recorded"), std::string::npos);
}

TEST(FrfEstimationBadRuns, WelchRunShorterThanTwoWindowsIsRefused) {
  RunRecording run = read_run(testing::data_file("external/amrotor_mlps_sweep").string());
  FrfEstimationOptions opt;
  opt.method = NonperiodicMethod::welch;
  opt.nfft = 32768;
  EXPECT_THROW(estimate_frf(run, opt), InputError);
  opt.nfft = 3;
  EXPECT_THROW(estimate_frf(run, opt), InputError);
}

}  // namespace
}  // namespace ambdiag
