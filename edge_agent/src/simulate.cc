#include "ambdiag/edge_agent/simulate.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <complex>
#include <ctime>
#include <map>
#include <numbers>
#include <limits>
#include <optional>
#include <random>

#include "ambdiag/algorithms/diagnosis/fault_models.h"
#include "ambdiag/core/error.h"

namespace ambdiag::agent {
namespace {

constexpr double kPi = std::numbers::pi;

std::string utc_now_iso() {
  const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

// Unbalance of balance grade G 2.5 (ISO 21940), the healthy residual:
// e Omega = 2.5 mm/s, u = m e.
double residual_unbalance_kg_m(const PlantModel& p) {
  const double omega = p.speed_rpm * 2 * kPi / 60.0;
  return omega > 0 ? p.rotor_mass_kg() * 2.5e-3 / omega : 0.0;
}

int impeller_node(const PlantModel& p) {
  for (const auto& d : p.disks)
    if (d.name == "impeller") return d.node;
  return p.node_count() / 2;
}

// The fault names and their default values where they do not depend on the
// plant (unbalance: 10 x the residual; plant faults: kPlantFaults).
const std::vector<std::string> kFaultNames = {"sensor_fault", "actuator_fault", "unbalance", "dry_run",
                                              "balance_piston_wear", "impeller_seal_wear", "rotor_crack",
                                              "shaft_nut_loosening"};

const std::map<std::string, std::pair<FaultKind, double>>& plant_faults() {
  static const std::map<std::string, std::pair<FaultKind, double>> k = {
      {"dry_run", {FaultKind::dry_run, 0.0}},
      {"balance_piston_wear", {FaultKind::balance_piston_wear, 2.0}},
      {"impeller_seal_wear", {FaultKind::impeller_seal_wear, 2.0}},
      {"rotor_crack", {FaultKind::rotor_crack, 0.5}},
      {"shaft_nut_loosening", {FaultKind::shaft_nut_loosening, 0.5}}};
  return k;
}

std::string join_names() {
  std::string out;
  for (const auto& n : kFaultNames) out += (out.empty() ? "" : ", ") + n;
  return out;
}

// A 64-bit seed from a few words: std::seed_seq mixes them, so nearby
// seeds and runs give unrelated streams.
uint64_t mixed_seed(uint64_t a, uint64_t b, uint32_t tag) {
  std::seed_seq seq{static_cast<uint32_t>(a), static_cast<uint32_t>(a >> 32), static_cast<uint32_t>(b),
                    static_cast<uint32_t>(b >> 32), tag};
  std::array<uint32_t, 2> w{};
  seq.generate(w.begin(), w.end());
  return (static_cast<uint64_t>(w[0]) << 32) | w[1];
}

// N(0, 1) cut at 3 sigma (drawn again beyond), so a coefficient factor
// 1 + sigma z stays positive for any sigma the options allow (<= 20 %).
double cut_normal(std::mt19937_64& g) {
  std::normal_distribution<double> n(0.0, 1.0);
  for (;;) {
    const double z = n(g);
    if (std::abs(z) <= 3.0) return z;
  }
}

// The plant-fault hypothesis of that name: seals by kind, a crack in the
// element left of the impeller, the impeller's hub joint.
const FaultHypothesis* plant_hypothesis(const std::vector<FaultHypothesis>& hs, FaultKind kind, int crack_element) {
  for (const auto& h : hs) {
    if (h.kind != kind) continue;
    if (kind == FaultKind::rotor_crack && (h.elements.empty() || h.elements.front() != crack_element)) continue;
    return &h;
  }
  return nullptr;
}

// Amplitude and phase of the component at w (rad/s) of samples v at fs, by
// least squares on cos/sin (the window need not hold whole periods).
std::pair<double, double> harmonic(const Eigen::RowVectorXd& v, double w, double fs) {
  double cc = 0, ss = 0, cs = 0, vc = 0, vs = 0;
  for (Eigen::Index k = 0; k < v.size(); ++k) {
    const double t = static_cast<double>(k) / fs, c = std::cos(w * t), s = std::sin(w * t);
    cc += c * c, ss += s * s, cs += c * s, vc += v(k) * c, vs += v(k) * s;
  }
  const double det = cc * ss - cs * cs;
  if (!(det > 0)) return {0.0, 0.0};
  const double a = (vc * ss - vs * cs) / det, b = (vs * cc - vc * cs) / det;  // v ~ a cos + b sin
  return {std::hypot(a, b), std::atan2(-b, a)};                                 // amp cos(w t + phase)
}

}  // namespace

struct PumpSimulator::ScheduledFault {
  FaultSchedule spec;
  enum class Target { sensor, actuator, unbalance, plant } target = Target::plant;
  FaultHypothesis hypothesis;  // plant faults
  double healthy = 1.0, start = 1.0, end = 1.0;
  int64_t to_run = 1;

  double value_at(int64_t run) const {
    if (run < spec.from_run) return healthy;
    if (!spec.end_value || run >= to_run) return spec.end_value ? end : start;
    return start + (end - start) * static_cast<double>(run - spec.from_run) / static_cast<double>(to_run - spec.from_run);
  }
};

PumpSimulator::~PumpSimulator() = default;

PumpSimulator::PumpSimulator(const std::string& model_path, SimulationOptions opt)
    : PumpSimulator(read_plant_file(model_path), std::move(opt)) {}

PumpSimulator::PumpSimulator(PlantModel plant, SimulationOptions opt) : base_(std::move(plant)), opt_(std::move(opt)) {
  if (base_.sensors.empty() || base_.actuators.empty())
    throw InputError("the simulator needs sensors and actuators in the plant model");
  if (opt_.excitation != "multisine" && opt_.excitation != "stepsine")
    throw InputError("excitation must be multisine or stepsine, got '" + opt_.excitation + "'");
  if (!(opt_.sample_rate_hz > 0) || opt_.period_samples < 8 || opt_.settle_periods < 0 || opt_.meas_periods < 1 ||
      !(opt_.f_min_hz > 0) || !(opt_.f_max_hz > opt_.f_min_hz) || opt_.f_max_hz >= opt_.sample_rate_hz / 2 ||
      opt_.stepsine_steps < 1 || !(opt_.monitoring_s > 0))
    throw InputError("simulation options: need sample rate > 0, 0 < f_min < f_max < Nyquist, periods >= 1");
  for (const double pct : {opt_.speed_spread_pct, opt_.seal_drift_pct, opt_.seal_drift_link_pct})
    if (!(pct >= 0 && pct <= 20))
      throw InputError("simulation options: speed spread and seal drift must be in 0..20 %");
  if (opt_.runs < 0) throw InputError("simulation options: runs must be >= 0");
  AmbLoopOptions& lo = opt_.loop;
  lo.decimation = static_cast<int>(std::ceil(8000.0 / opt_.sample_rate_hz - 1e-9));
  lo.decimation = std::max(lo.decimation, 1);
  lo.controller_rate_hz = opt_.sample_rate_hz * lo.decimation;
  lo.seed = opt_.seed;
  lo.unbalance_node = impeller_node(base_);
  // u is a property of the rotor: fixed at the model speed's G 2.5 value,
  // its force u Omega^2 follows each run's speed.
  lo.unbalance_kg_m = residual_unbalance_kg_m(base_) * opt_.unbalance_grade_mm_per_s / 2.5;
  seal_links_ = fluid_seal_links(base_);

  const std::vector<FaultHypothesis> hyps = fault_hypotheses(base_);
  const int crack_element = std::max(0, impeller_node(base_) - 1);
  for (const auto& text : opt_.faults) {
    ScheduledFault f;
    f.spec = parse_fault_schedule(text);
    double lower = 0, upper = std::numeric_limits<double>::infinity(), fallback = 0;
    std::string parameter = "value";
    if (f.spec.name == "sensor_fault" || f.spec.name == "actuator_fault") {
      f.target = f.spec.name == "sensor_fault" ? ScheduledFault::Target::sensor : ScheduledFault::Target::actuator;
      fallback = f.spec.name == "sensor_fault" ? 0.8 : 0.7;
      parameter = "gain";
    } else if (f.spec.name == "unbalance") {
      f.target = ScheduledFault::Target::unbalance;
      f.healthy = lo.unbalance_kg_m;
      fallback = 10.0 * residual_unbalance_kg_m(base_);
      parameter = "u (kg m)";
    } else {
      const auto& [kind, dflt] = plant_faults().at(f.spec.name);  // the name is known: parse_fault_schedule
      const FaultHypothesis* h = plant_hypothesis(hyps, kind, crack_element);
      if (!h) throw InputError("--fault " + f.spec.name + ": the plant model has nothing this fault acts on");
      f.hypothesis = *h;
      f.healthy = h->nominal;
      fallback = dflt;
      lower = h->lower, upper = h->upper, parameter = h->parameter;
    }
    f.start = f.spec.value.value_or(fallback);
    f.end = f.spec.end_value.value_or(f.start);
    for (const double v : {f.start, f.end})
      if (v < lower || v > upper)
        throw InputError("--fault " + text + ": " + parameter + " must be in [" + std::to_string(lower) + ", " +
                         std::to_string(upper) + "]");
    if (f.spec.end_value) {
      f.to_run = f.spec.to_run.value_or(opt_.runs);
      if (f.to_run == 0)
        throw InputError("--fault " + text + ": a ramp A..B ends at the last run: give --runs N or @runK..M");
      if (f.to_run < f.spec.from_run)
        throw InputError("--fault " + text + ": the ramp starts at run " + std::to_string(f.spec.from_run) +
                         ", after the last run " + std::to_string(f.to_run));
    }
    faults_.push_back(std::move(f));
  }
  build_loop(operating_state(1), opt_.seed);
}

FaultSchedule parse_fault_schedule(const std::string& text) {
  auto bad = [&](const std::string& why) {
    throw InputError("--fault '" + text + "': " + why + " (syntax NAME[=V|=A..B][@runK[..M]])");
  };
  auto number = [&](const std::string& v) {
    char* end = nullptr;
    const double x = std::strtod(v.c_str(), &end);
    if (v.empty() || *end != '\0' || !std::isfinite(x) || x < 0) bad("'" + v + "' is not a number >= 0");
    return x;
  };
  auto run_number = [&](const std::string& v) {
    if (v.empty() || v.size() > 9 || v.find_first_not_of("0123456789") != std::string::npos || std::stoll(v) < 1)
      bad("'" + v + "' is not a run number >= 1");
    return static_cast<int64_t>(std::stoll(v));
  };
  FaultSchedule f;
  f.text = text;
  const auto at = text.find('@');
  const std::string head = text.substr(0, at);
  const auto eq = head.find('=');
  f.name = head.substr(0, eq);
  if (std::find(kFaultNames.begin(), kFaultNames.end(), f.name) == kFaultNames.end())
    throw InputError("--fault " + f.name + ": unknown fault (" + join_names() + ")");
  if (eq != std::string::npos) {
    const std::string v = head.substr(eq + 1);
    if (const auto dots = v.find(".."); dots == std::string::npos) {
      f.value = number(v);
    } else {
      f.value = number(v.substr(0, dots));
      f.end_value = number(v.substr(dots + 2));
    }
  }
  if (at != std::string::npos) {
    const std::string tail = text.substr(at + 1);
    if (!tail.starts_with("run")) bad("the onset is written @runK");
    const std::string r = tail.substr(3);
    const auto dots = r.find("..");
    f.from_run = run_number(r.substr(0, dots));
    if (dots != std::string::npos) {
      if (!f.end_value) bad("@runK..M ends a ramp A..B; a constant value takes @runK");
      f.to_run = run_number(r.substr(dots + 2));
      if (*f.to_run < f.from_run) bad("the ramp ends before it starts");
    }
  }
  return f;
}

const std::vector<std::string>& simulated_fault_names() { return kFaultNames; }

bool OperatingState::same_pump(const OperatingState& o) const {
  if (speed_factor != o.speed_factor || seal_factor != o.seal_factor || faults.size() != o.faults.size()) return false;
  for (size_t i = 0; i < faults.size(); ++i)
    if (faults[i].value != o.faults[i].value) return false;
  return true;
}

nlohmann::json OperatingState::to_json() const {
  nlohmann::json seals = nlohmann::json::object(), fs = nlohmann::json::array();
  for (const auto& [name, factor] : seal_factor) seals[name] = factor;
  for (const auto& f : faults) fs.push_back({{"spec", f.spec}, {"name", f.name}, {"value", f.value}, {"active", f.active}});
  return {{"run", run}, {"speed_factor", speed_factor}, {"speed_rpm", speed_rpm}, {"seal_drift", seal_drift},
          {"seal_factors", seals}, {"faults", fs}};
}

OperatingState PumpSimulator::operating_state(int64_t run) const {
  OperatingState st;
  st.run = run;
  // Every draw is made whatever the options, in a fixed order, so turning
  // one option on leaves the others' draws as they were.
  std::mt19937_64 g(mixed_seed(opt_.operating_seed.value_or(opt_.seed), static_cast<uint64_t>(run), 0x6f7065u));
  const double u = std::uniform_real_distribution<double>(-1.0, 1.0)(g);
  const double z = cut_normal(g);
  st.speed_factor = 1.0 + opt_.speed_spread_pct / 100.0 * u;
  st.speed_rpm = base_.speed_rpm * st.speed_factor;
  st.seal_drift = opt_.seal_drift_pct / 100.0 * z;
  for (const int i : seal_links_) {
    const double d_link = opt_.seal_drift_link_pct / 100.0 * cut_normal(g);
    st.seal_factor.emplace_back(base_.links[static_cast<size_t>(i)].name, (1.0 + st.seal_drift) * (1.0 + d_link));
  }
  for (const auto& f : faults_) {
    const double v = f.value_at(run);
    st.faults.push_back({f.spec.text, f.spec.name, v, v != f.healthy});
  }
  return st;
}

// Changes are made only where a factor differs from 1 or a value from the
// healthy one, so the healthy operating point gives exactly the model.
PlantModel PumpSimulator::plant_of(const OperatingState& st) const {
  PlantModel p = base_;
  p.speed_rpm = st.speed_rpm;
  for (size_t k = 0; k < seal_links_.size(); ++k)
    if (st.seal_factor[k].second != 1.0) scale_link(p.links[static_cast<size_t>(seal_links_[k])], st.seal_factor[k].second);
  for (size_t k = 0; k < faults_.size(); ++k)
    if (faults_[k].target == ScheduledFault::Target::plant && st.faults[k].active)
      p = apply_fault(p, faults_[k].hypothesis, st.faults[k].value);
  return p;
}

AmbLoopOptions PumpSimulator::loop_options_of(const OperatingState& st) const {
  AmbLoopOptions lo = opt_.loop;
  for (size_t k = 0; k < faults_.size(); ++k) {
    if (!st.faults[k].active) continue;
    const double v = st.faults[k].value;
    switch (faults_[k].target) {
      case ScheduledFault::Target::sensor:
        lo.sensor_gain.assign(base_.sensors.size(), 1.0);
        lo.sensor_gain[0] = v;
        break;
      case ScheduledFault::Target::actuator:
        lo.actuator_gain.assign(base_.actuators.size(), 1.0);
        lo.actuator_gain[0] = v;
        break;
      case ScheduledFault::Target::unbalance: lo.unbalance_kg_m = v; break;
      case ScheduledFault::Target::plant: break;
    }
  }
  return lo;
}

void PumpSimulator::build_loop(const OperatingState& st, uint64_t noise_seed) {
  const auto t0 = std::chrono::steady_clock::now();
  AmbLoopOptions lo = loop_options_of(st);
  lo.seed = noise_seed;
  PlantModel p = plant_of(st);
  loop_ = std::make_unique<AmbLoop>(p, lo);
  plant_ = std::move(p);
  state_ = st;
  last_rebuild_s_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void PumpSimulator::set_operating_state(int64_t run) {
  OperatingState st = operating_state(run);
  if (st.same_pump(state_)) {
    state_ = std::move(st);  // same pump: keep the loop, its state and its noise
    last_rebuild_s_ = 0.0;
    return;
  }
  // Noise of its own per rebuilt run (a rebuilt loop seeded like the first
  // would repeat the first run's noise).
  build_loop(st, mixed_seed(opt_.seed, static_cast<uint64_t>(run), 0x6e6f69u));
}

RunRecording PumpSimulator::new_run(const std::string& kind) {
  RunRecording run;
  run.pump_id = opt_.pump_id;
  run.run_id = opt_.pump_id + "/sim-" + std::to_string(++runs_) + "-" + utc_now_iso();
  run.kind = kind;
  run.started_at = utc_now_iso();
  run.speed_rpm = plant_.speed_rpm;
  run.sample_rate_hz = opt_.sample_rate_hz;
  for (const auto& a : plant_.actuators)
    run.channels.push_back({"r" + a.name, ChannelRole::reference, "reference", "N", a.name, nlohmann::json::object()});
  for (const auto& a : plant_.actuators)
    run.channels.push_back({a.name, ChannelRole::force, "force", "N", "", nlohmann::json::object()});
  for (const auto& s : plant_.sensors)
    run.channels.push_back({s.name, ChannelRole::displacement, "displacement", "m", "", nlohmann::json::object()});
  run.channels.push_back({"speed", ChannelRole::speed, "speed", "rpm", "", nlohmann::json::object()});
  return run;
}

void PumpSimulator::append(RunRecording& run, const Eigen::MatrixXd& r, const Eigen::MatrixXd& f,
                           const Eigen::MatrixXd& x) const {
  const size_t n_ch = run.channels.size();
  const size_t old = run.samples.size();
  run.samples.resize(old + static_cast<size_t>(r.cols()) * n_ch);
  float* row = run.samples.data() + old;
  for (Eigen::Index k = 0; k < r.cols(); ++k, row += n_ch) {
    size_t c = 0;
    for (Eigen::Index j = 0; j < r.rows(); ++j) row[c++] = static_cast<float>(r(j, k));
    for (Eigen::Index j = 0; j < f.rows(); ++j) row[c++] = static_cast<float>(f(j, k));
    for (Eigen::Index i = 0; i < x.rows(); ++i) row[c++] = static_cast<float>(x(i, k));
    row[c] = static_cast<float>(plant_.speed_rpm);
  }
}

RunRecording PumpSimulator::identification_run() {
  set_operating_state(runs_ + 1);
  RunRecording run = opt_.excitation == "multisine" ? multisine_run() : stepsine_run();
  run.extra["simulation"] = state_.to_json();
  run.validate();
  return run;
}

RunRecording PumpSimulator::multisine_run() {
  RunRecording run = new_run("identification");
  const size_t n_in = plant_.actuators.size();
  const int dec = opt_.loop.decimation;
  const int64_t N = opt_.period_samples, Nc = N * dec;
  const double df = opt_.sample_rate_hz / static_cast<double>(N);
  std::vector<int64_t> bins;
  for (auto k = static_cast<int64_t>(std::ceil(opt_.f_min_hz / df - 1e-9)); static_cast<double>(k) * df <= opt_.f_max_hz + 1e-9; ++k)
    bins.push_back(k);
  if (bins.empty()) throw InputError("multisine: no line between f_min and f_max");
  // One period of z(n) = sum_k A e^{j phi_k} e^{j 2 pi k n / N} at the
  // controller rate; input j of pattern p is Re(e^{j 2 pi p j / n_in} z).
  std::mt19937_64 rng(opt_.seed * 7919 + static_cast<uint64_t>(runs_));
  std::uniform_real_distribution<double> uni(0.0, 2 * kPi);
  const double amp = opt_.force_rms_n * std::sqrt(2.0 / static_cast<double>(bins.size()));
  std::vector<std::complex<double>> z(static_cast<size_t>(Nc), 0.0);
  for (const int64_t b : bins) {
    const std::complex<double> step = std::polar(1.0, 2 * kPi * static_cast<double>(b) / static_cast<double>(Nc));
    std::complex<double> w = std::polar(amp, uni(rng));
    for (auto& v : z) v += w, w *= step;
  }
  Excitation ex;
  ex.type = ExcitationType::multisine;
  ex.period_samples = N;
  ex.f_min_hz = static_cast<double>(bins.front()) * df;
  ex.f_max_hz = static_cast<double>(bins.back()) * df;
  const int periods = opt_.settle_periods + opt_.meas_periods;
  Eigen::MatrixXd r, f, x;
  for (size_t p = 0; p < n_in; ++p) {
    ExcitationSegment seg;
    seg.start = run.frame_count();
    seg.periods = periods;
    seg.settle_periods = opt_.settle_periods;
    seg.pattern = static_cast<int>(p);
    ex.segments.push_back(seg);
    std::vector<std::complex<double>> rot(n_in);
    for (size_t j = 0; j < n_in; ++j) rot[j] = std::polar(1.0, 2 * kPi * static_cast<double>(p * j) / static_cast<double>(n_in));
    loop_->run(periods * N, [&](int64_t k, std::span<double> out) {
      const std::complex<double> v = z[static_cast<size_t>(k % Nc)];
      for (size_t j = 0; j < n_in; ++j) out[j] = (rot[j] * v).real();
    }, r, f, x);
    append(run, r, f, x);
  }
  run.excitation = ex;
  return run;
}

RunRecording PumpSimulator::stepsine_run() {
  RunRecording run = new_run("identification");
  const size_t n_in = plant_.actuators.size();
  const double fs = opt_.sample_rate_hz, fc = fs * opt_.loop.decimation;
  const auto settle = static_cast<int64_t>(std::ceil(opt_.stepsine_settle_s * fs));
  Excitation ex;
  ex.type = ExcitationType::stepsine;
  Eigen::MatrixXd r, f, x;
  for (size_t j = 0; j < n_in; ++j) {
    for (int s = 0; s < opt_.stepsine_steps; ++s) {
      const double frac = opt_.stepsine_steps > 1 ? static_cast<double>(s) / (opt_.stepsine_steps - 1) : 0.0;
      const double f_want = opt_.f_min_hz * std::pow(opt_.f_max_hz / opt_.f_min_hz, frac);
      // Whole periods in the measured part: P periods in M samples, f = P fs / M.
      const auto periods = std::max<int64_t>(1, std::llround(std::ceil(f_want * opt_.stepsine_meas_s)));
      const auto meas = std::max<int64_t>(4, std::llround(static_cast<double>(periods) * fs / f_want));
      ExcitationSegment seg;
      seg.start = run.frame_count();
      seg.input = plant_.actuators[j].name;
      seg.freq_hz = static_cast<double>(periods) * fs / static_cast<double>(meas);
      seg.amplitude = opt_.stepsine_amplitude_n;
      seg.settle_samples = settle;
      seg.meas_samples = meas;
      seg.periods = periods;
      seg.length = settle + meas;
      ex.segments.push_back(seg);
      const double w = 2 * kPi * seg.freq_hz / fc;
      loop_->run(seg.length, [&](int64_t k, std::span<double> out) {
        std::fill(out.begin(), out.end(), 0.0);
        out[j] = seg.amplitude * std::sin(w * static_cast<double>(k));
      }, r, f, x);
      append(run, r, f, x);
    }
  }
  ex.f_min_hz = ex.segments.front().freq_hz;
  ex.f_max_hz = ex.segments.back().freq_hz;
  for (const auto& s : ex.segments) ex.f_min_hz = std::min(ex.f_min_hz, s.freq_hz), ex.f_max_hz = std::max(ex.f_max_hz, s.freq_hz);
  run.excitation = ex;
  return run;
}

Snapshot PumpSimulator::monitoring_snapshot() {
  const auto n = static_cast<int64_t>(std::ceil(opt_.monitoring_s * opt_.sample_rate_hz));
  Eigen::MatrixXd r, f, x;
  loop_->run(n, [](int64_t, std::span<double> out) { std::fill(out.begin(), out.end(), 0.0); }, r, f, x);
  Snapshot s;
  s.speed_rpm = plant_.speed_rpm;
  const double w = plant_.speed_rpm * 2 * kPi / 60.0, fs = opt_.sample_rate_hz;
  auto slot = [](const MeasurementPoint& p) {
    if (p.is_axial() || (p.plane != "A" && p.plane != "B")) return -1;
    return (p.plane == "B" ? 2 : 0) + (p.dir == 'y' ? 1 : 0);
  };
  for (size_t j = 0; j < plant_.actuators.size(); ++j) {
    const int k = slot(plant_.actuators[j]);
    if (k < 0 || w <= 0) continue;
    const auto h1 = harmonic(f.row(static_cast<Eigen::Index>(j)), w, fs), h2 = harmonic(f.row(static_cast<Eigen::Index>(j)), 2 * w, fs);
    s.force_1x_amp_n[static_cast<size_t>(k)] = h1.first;
    s.force_1x_phase_rad[static_cast<size_t>(k)] = h1.second;
    s.force_2x_amp_n[static_cast<size_t>(k)] = h2.first;
    s.force_2x_phase_rad[static_cast<size_t>(k)] = h2.second;
  }
  // Orbit of each bearing from its x and y sensors: centre = mean, semi-axes
  // from the covariance (sqrt(2 lambda): exact for an elliptic 1x orbit).
  double sum_sq = 0;
  int lateral = 0;
  for (int b = 0; b < 2; ++b) {
    Eigen::Index ix = -1, iy = -1;
    for (size_t i = 0; i < plant_.sensors.size(); ++i) {
      const int k = slot(plant_.sensors[i]);
      if (k == 2 * b) ix = static_cast<Eigen::Index>(i);
      if (k == 2 * b + 1) iy = static_cast<Eigen::Index>(i);
    }
    if (ix < 0 || iy < 0) continue;
    const double mx = x.row(ix).mean(), my = x.row(iy).mean();
    const Eigen::RowVectorXd dx = x.row(ix).array() - mx, dy = x.row(iy).array() - my;
    const double nn = static_cast<double>(n);
    const double sxx = dx.squaredNorm() / nn, syy = dy.squaredNorm() / nn, sxy = dx.dot(dy) / nn;
    const double tr = sxx + syy, disc = std::sqrt(std::max(0.0, (sxx - syy) * (sxx - syy) / 4 + sxy * sxy));
    s.orbit_major_m[static_cast<size_t>(b)] = std::sqrt(2 * (tr / 2 + disc));
    s.orbit_minor_m[static_cast<size_t>(b)] = std::sqrt(2 * std::max(0.0, tr / 2 - disc));
    s.orbit_center_x_m[static_cast<size_t>(b)] = mx;
    s.orbit_center_y_m[static_cast<size_t>(b)] = my;
  }
  for (size_t i = 0; i < plant_.sensors.size(); ++i)
    if (!plant_.sensors[i].is_axial()) sum_sq += x.row(static_cast<Eigen::Index>(i)).squaredNorm() / static_cast<double>(n), ++lateral;
  s.displacement_rms_m = lateral > 0 ? std::sqrt(sum_sq / lateral) : 0.0;
  return s;
}

}  // namespace ambdiag::agent
