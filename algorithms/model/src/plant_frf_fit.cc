#include "ambdiag/algorithms/model/plant_frf_fit.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/core/error.h"
#include "frf_terms.h"

namespace ambdiag {

namespace {

// The part of the plant that the lateral rotor FRF depends on: no housings,
// no axial model, lateral points only.
PlantModel rotor_part(const PlantModel& p) {
  PlantModel r = p;
  r.name.clear();
  r.housings.clear();
  r.axial.reset();
  auto lateral_only = [](std::vector<MeasurementPoint>& v) {
    v.erase(std::remove_if(v.begin(), v.end(), [](const MeasurementPoint& m) { return m.is_axial(); }), v.end());
  };
  lateral_only(r.sensors);
  lateral_only(r.actuators);
  return r;
}

// Every value the lateral rotor FRF depends on, as raw bytes (a cache key:
// cheaper than serialising the JSON of the rotor part on every evaluation).
class Fingerprint {
 public:
  template <typename T>
  void add(const T& v) {
    key_.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  void add(const std::string& s) {
    add(s.size());
    key_ += s;
  }
  std::string take() { return std::move(key_); }

 private:
  std::string key_;
};

std::string rotor_fingerprint(const PlantModel& p, double rpm) {
  Fingerprint f;
  f.add(rpm);
  for (const auto& [name, m] : p.materials) {
    f.add(name);
    f.add(m.e_pa), f.add(m.g_pa), f.add(m.rho_kg_per_m3);
  }
  f.add(p.shaft.size());
  for (const auto& e : p.shaft) {
    f.add(e.length_m), f.add(e.od_m), f.add(e.id_m), f.add(e.material), f.add(e.added_mass_kg_per_m);
  }
  f.add(p.disks.size());
  for (const auto& d : p.disks) f.add(d.node), f.add(d.m_kg), f.add(d.id_kg_m2), f.add(d.ip_kg_m2);
  f.add(p.links.size());
  for (const auto& l : p.links) {
    f.add(l.node);
    for (double c : l.coef) f.add(c);
    f.add(l.table.size());
    for (const auto& row : l.table) {
      f.add(row.rpm);
      for (const auto& v : row.values) f.add(v ? 1 : 0), f.add(v.value_or(0.0));
    }
  }
  f.add(static_cast<int>(p.structural_damping.kind)), f.add(p.structural_damping.zeta);
  f.add(static_cast<int>(p.reduction.kind)), f.add(p.reduction.n_elastic_modes);
  for (const auto* points : {&p.sensors, &p.actuators}) {
    f.add(points->size());
    for (const auto& m : *points) {
      if (m.is_axial()) continue;
      f.add(m.name), f.add(m.plane), f.add(m.node.value_or(-1)), f.add(m.dir);
    }
  }
  return f.take();
}

std::string lines_key(const std::vector<int>& lines) {
  long s = 0;
  for (size_t k = 0; k < lines.size(); ++k) s += static_cast<long>(lines[k]) * static_cast<long>(k % 7 + 1);
  return std::to_string(lines.size()) + ":" + std::to_string(s);
}

}  // namespace

PlantFrfEvaluator::PlantFrfEvaluator(const FrfData& measured) : measured_(measured) {
  measured_.validate();
  for (const auto& e : measured_.entries) {
    std::vector<double> s = e.sigma;
    if (s.size() != e.h.size()) {
      double ms = 0.0;
      for (const auto& h : e.h) ms += std::norm(h);
      const double rms = std::sqrt(ms / static_cast<double>(std::max<size_t>(1, e.h.size())));
      s.assign(e.h.size(), 0.01 * rms);
    }
    // A zero sigma would make the line infinitely certain: floor it.
    double mx = 0.0;
    for (double v : s) mx = std::max(mx, v);
    for (double& v : s) v = std::max(v, 1e-6 * mx + std::numeric_limits<double>::min());
    sigma_.push_back(std::move(s));
  }
}

std::string PlantFrfEvaluator::rotor_key(const PlantModel& plant) const { return rotor_fingerprint(plant, speed_rpm(plant)); }

double PlantFrfEvaluator::speed_rpm(const PlantModel& plant) const { return measured_.speed_rpm.value_or(plant.speed_rpm); }

const std::vector<std::vector<std::complex<double>>>& PlantFrfEvaluator::lateral(const PlantModel& plant,
                                                                                const std::vector<int>& lines) {
  const std::string key = lines_key(lines) + "|" + rotor_key(plant);
  if (auto it = cache_.find(key); it != cache_.end()) return it->second;
  const PlantModel rp = rotor_part(plant);
  if (cache_.size() > 256) cache_.clear();

  std::vector<std::vector<std::complex<double>>> out(measured_.entries.size());
  if (!rp.sensors.empty() && !rp.actuators.empty()) {
    std::vector<double> f;
    f.reserve(lines.size());
    for (int l : lines) f.push_back(measured_.freq_hz[static_cast<size_t>(l)]);
    const FrfData lat = synthesize_frf(rp, speed_rpm(plant), f, {FrfMethod::modal});
    ++rotor_solves_;
    for (size_t e = 0; e < measured_.entries.size(); ++e) {
      if (const FrfEntry* m = lat.find(measured_.entries[e].output, measured_.entries[e].input)) out[e] = m->h;
    }
  }
  return cache_.emplace(key, std::move(out)).first->second;
}

std::vector<std::vector<std::complex<double>>> PlantFrfEvaluator::model_h(const PlantVariant& v, const std::vector<int>& lines) {
  const PlantModel& p = v.plant;
  const auto& lat = lateral(p, lines);
  std::vector<std::vector<std::complex<double>>> out(measured_.entries.size());
  for (size_t e = 0; e < measured_.entries.size(); ++e) {
    const FrfEntry& me = measured_.entries[e];
    const MeasurementPoint* s = p.find_sensor(me.output);
    const MeasurementPoint* a = p.find_actuator(me.input);
    if (!s || !a) throw InputError("measured entry " + me.output + "/" + me.input + ": the plant model has no such sensor/actuator pair");
    if ((s->is_axial() || a->is_axial()) && s->is_axial() == a->is_axial() && !p.axial)
      throw InputError("measured entry " + me.output + "/" + me.input + ": axial entry but the plant model has no axial model");
    auto& h = out[e];
    h.resize(lines.size());
    std::vector<double> omega(lines.size());
    for (size_t k = 0; k < lines.size(); ++k) omega[k] = 2.0 * M_PI * measured_.freq_hz[static_cast<size_t>(lines[k])];
    const std::vector<std::complex<double>> parallel = detail::parallel_compliances(p, *s, *a, omega);
    for (size_t k = 0; k < lines.size(); ++k) {
      const double w = omega[k];
      std::complex<double> v0 = parallel[k];
      if (!lat[e].empty()) v0 += lat[e][k];
      if (v.delay_s != 0.0) v0 *= std::polar(1.0, -w * v.delay_s);
      h[k] = v0;
    }
  }
  return out;
}

std::vector<std::complex<double>> PlantFrfEvaluator::residual(const PlantVariant& v, const std::vector<int>& lines) {
  const auto h = model_h(v, lines);
  std::vector<std::complex<double>> r;
  r.reserve(h.size() * lines.size());
  for (size_t e = 0; e < h.size(); ++e) {
    for (size_t k = 0; k < lines.size(); ++k) {
      const size_t l = static_cast<size_t>(lines[k]);
      r.push_back((h[e][k] - measured_.entries[e].h[l]) / sigma_[e][l]);
    }
  }
  return r;
}

FrfData PlantFrfEvaluator::model_frf(const PlantVariant& v) {
  std::vector<int> all(measured_.freq_hz.size());
  for (size_t l = 0; l < all.size(); ++l) all[l] = static_cast<int>(l);
  const auto h = model_h(v, all);
  FrfData out;
  out.freq_hz = measured_.freq_hz;
  out.speed_rpm = speed_rpm(v.plant);
  for (size_t e = 0; e < h.size(); ++e) out.entries.push_back({measured_.entries[e].output, measured_.entries[e].input, h[e], {}, {}});
  return out;
}

LeastSquaresResult fit_parameters(PlantFrfEvaluator& eval, const VariantBuilder& build, const std::vector<FitParameter>& params,
                                  const std::vector<int>& lines, const LeastSquaresOptions& options) {
  return fit_least_squares([&](const std::vector<double>& x) { return eval.residual(build(x), lines); }, params, options);
}

}  // namespace ambdiag
