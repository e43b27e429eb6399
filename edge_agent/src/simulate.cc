#include "ambdiag/edge_agent/simulate.h"

#include <chrono>
#include <cmath>
#include <complex>
#include <ctime>
#include <numbers>
#include <random>
#include <set>

#include "ambdiag/algorithms/frf_synthesis.h"
#include "ambdiag/core/error.h"

namespace ambdiag::agent {
namespace {

using cd = std::complex<double>;

std::string utc_now_iso() {
  const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

}  // namespace

PumpSimulator::PumpSimulator(const std::string& model_path, SimulationOptions opt)
    : plant_(read_plant_file(model_path)), opt_(std::move(opt)) {
  static const std::set<std::string> kSupported = {"sensor_fault", "actuator_fault", "unbalance"};
  for (const auto& f : opt_.faults)
    if (!kSupported.count(f))
      throw InputError("--fault " + f + ": the simulator injects only sensor_fault, actuator_fault and unbalance so far");
  if (plant_.sensors.empty() || plant_.actuators.empty())
    throw InputError(model_path + ": the simulator needs sensors and actuators in the plant model");
}

RunRecording PumpSimulator::identification_run() {
  const size_t n_in = plant_.actuators.size(), n_out = plant_.sensors.size();
  const int64_t N = opt_.period_samples;
  const double fs = opt_.sample_rate_hz, df = fs / static_cast<double>(N);
  std::vector<int64_t> bins;
  std::vector<double> freqs;
  for (int64_t k = static_cast<int64_t>(std::ceil(opt_.f_min_hz / df)); k * df <= opt_.f_max_hz; ++k) {
    bins.push_back(k);
    freqs.push_back(static_cast<double>(k) * df);
  }
  const FrfData H = synthesize_frf(plant_, plant_.speed_rpm, freqs);

  std::mt19937_64 rng(opt_.seed + static_cast<uint64_t>(runs_));
  std::uniform_real_distribution<double> uni(0.0, 2 * std::numbers::pi);
  std::vector<double> phase(bins.size());
  for (auto& p : phase) p = uni(rng);
  const double amp = opt_.force_rms_n * std::sqrt(2.0 / static_cast<double>(bins.size()));

  RunRecording run;
  run.pump_id = opt_.pump_id;
  run.run_id = opt_.pump_id + "/sim-" + std::to_string(++runs_) + "-" + utc_now_iso();
  run.kind = "identification";
  run.started_at = utc_now_iso();
  run.speed_rpm = plant_.speed_rpm;
  run.sample_rate_hz = fs;
  for (const auto& a : plant_.actuators)
    run.channels.push_back({"r" + a.name, ChannelRole::reference, "reference", "N", a.name, nlohmann::json::object()});
  for (const auto& a : plant_.actuators)
    run.channels.push_back({a.name, ChannelRole::force, "force", "N", "", nlohmann::json::object()});
  for (const auto& s : plant_.sensors)
    run.channels.push_back({s.name, ChannelRole::displacement, "displacement", "m", "", nlohmann::json::object()});
  Excitation ex;
  ex.type = ExcitationType::multisine;
  ex.period_samples = N;
  ex.f_min_hz = freqs.front();
  ex.f_max_hz = freqs.back();
  const int periods = opt_.settle_periods + opt_.meas_periods;
  const size_t n_ch = run.channels.size();
  const int64_t frames = static_cast<int64_t>(n_in) * periods * N;
  run.samples.assign(static_cast<size_t>(frames) * n_ch, 0.0f);

  // One period per segment (the run is steady state: every period the same).
  std::vector<double> r(n_in * static_cast<size_t>(N)), x(n_out * static_cast<size_t>(N));
  for (size_t p = 0; p < n_in; ++p) {
    ExcitationSegment seg;
    seg.start = static_cast<int64_t>(p) * periods * N;
    seg.periods = periods;
    seg.settle_periods = opt_.settle_periods;
    seg.pattern = static_cast<int>(p);
    ex.segments.push_back(seg);
    std::fill(r.begin(), r.end(), 0.0);
    std::fill(x.begin(), x.end(), 0.0);
    for (size_t k = 0; k < bins.size(); ++k) {
      std::vector<cd> F(n_in);
      for (size_t j = 0; j < n_in; ++j)
        F[j] = std::polar(amp, phase[k] + 2 * std::numbers::pi * static_cast<double>(p * j) / static_cast<double>(n_in));
      std::vector<cd> X(n_out);
      for (size_t i = 0; i < n_out; ++i)
        for (size_t j = 0; j < n_in; ++j)
          if (const FrfEntry* e = H.find(plant_.sensors[i].name, plant_.actuators[j].name)) X[i] += e->h[k] * F[j];
      const cd step = std::polar(1.0, 2 * std::numbers::pi * static_cast<double>(bins[k]) / static_cast<double>(N));
      cd w = 1.0;
      for (int64_t n = 0; n < N; ++n, w *= step) {
        for (size_t j = 0; j < n_in; ++j) r[j * static_cast<size_t>(N) + static_cast<size_t>(n)] += (F[j] * w).real();
        for (size_t i = 0; i < n_out; ++i) x[i * static_cast<size_t>(N) + static_cast<size_t>(n)] += (X[i] * w).real();
      }
    }
    // Faults on the measurement chain, then noise.
    std::vector<double> gain_f(n_in, 1.0), gain_x(n_out, 1.0), offset_x(n_out, 0.0);
    for (const auto& f : opt_.faults) {
      if (f == "sensor_fault") gain_x[0] = 0.8, offset_x[0] = 20e-6;
      if (f == "actuator_fault") gain_f[0] = 0.7;
    }
    auto rms = [&](const std::vector<double>& v, size_t c) {
      double s = 0;
      for (int64_t n = 0; n < N; ++n) s += v[c * static_cast<size_t>(N) + static_cast<size_t>(n)] * v[c * static_cast<size_t>(N) + static_cast<size_t>(n)];
      return std::sqrt(s / static_cast<double>(N));
    };
    std::vector<double> sf(n_in), sx(n_out);
    for (size_t j = 0; j < n_in; ++j) sf[j] = opt_.noise_fraction * rms(r, j);
    for (size_t i = 0; i < n_out; ++i) sx[i] = opt_.noise_fraction * rms(x, i);
    std::normal_distribution<double> gauss(0.0, 1.0);
    const double omega_1x = plant_.speed_rpm / 60.0 * 2 * std::numbers::pi;
    const bool unbalance = std::find(opt_.faults.begin(), opt_.faults.end(), "unbalance") != opt_.faults.end();
    for (int64_t n = 0; n < periods * N; ++n) {
      const int64_t frame = seg.start + n;
      const size_t n0 = static_cast<size_t>(n % N);
      float* row = run.samples.data() + static_cast<size_t>(frame) * n_ch;
      const double t = static_cast<double>(frame) / fs;
      for (size_t j = 0; j < n_in; ++j) {
        row[j] = static_cast<float>(r[j * static_cast<size_t>(N) + n0]);
        row[n_in + j] = static_cast<float>(gain_f[j] * r[j * static_cast<size_t>(N) + n0] + sf[j] * gauss(rng));
      }
      for (size_t i = 0; i < n_out; ++i) {
        double v = gain_x[i] * x[i * static_cast<size_t>(N) + n0] + offset_x[i] + sx[i] * gauss(rng);
        if (unbalance && !plant_.sensors[i].is_axial())
          v += 10e-6 * (plant_.sensors[i].dir == 'x' ? std::cos(omega_1x * t) : std::sin(omega_1x * t));
        row[2 * n_in + i] = static_cast<float>(v);
      }
    }
  }
  run.excitation = ex;
  run.validate();
  return run;
}

}  // namespace ambdiag::agent
