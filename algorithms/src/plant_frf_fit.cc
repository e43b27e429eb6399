#include "ambdiag/algorithms/plant_frf_fit.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/frf_synthesis.h"
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

double chi2_of(const std::vector<std::complex<double>>& r) {
  double s = 0.0;
  for (const auto& v : r) s += std::norm(v);
  return s;
}

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

PlantFitResult fit_parameters(PlantFrfEvaluator& eval, const VariantBuilder& build, const std::vector<FitParameter>& params,
                                  const std::vector<int>& lines, const PlantFitOptions& options) {
  return fit_least_squares([&](const std::vector<double>& x) { return eval.residual(build(x), lines); }, params, options);
}

PlantFitResult fit_least_squares(const ResidualFunction& residual, const std::vector<FitParameter>& params,
                                     const PlantFitOptions& options) {
  const int p = static_cast<int>(params.size());
  PlantFitResult res;
  std::vector<double> x(params.size());
  for (int i = 0; i < p; ++i) x[i] = std::clamp(params[i].initial, params[i].lower, params[i].upper);
  auto residual_of = [&](const std::vector<double>& xv) {
    ++res.evaluations;
    return residual(xv);
  };
  auto stack = [](const std::vector<std::complex<double>>& r) {
    Eigen::VectorXd v(2 * static_cast<Eigen::Index>(r.size()));
    for (size_t k = 0; k < r.size(); ++k) {
      v(2 * static_cast<Eigen::Index>(k)) = r[k].real();
      v(2 * static_cast<Eigen::Index>(k) + 1) = r[k].imag();
    }
    return v;
  };
  Eigen::VectorXd r = stack(residual_of(x));
  double chi2 = r.squaredNorm();
  res.chi2_start = chi2;
  res.stop_reason = "no parameters";
  Eigen::MatrixXd jac(r.size(), p);
  double lambda = 1e-3;
  bool have_jac = false;
  for (int it = 0; it < options.max_iterations && p > 0; ++it) {
    res.iterations = it + 1;
    for (int i = 0; i < p; ++i) {  // forward differences in the scaled coordinate
      std::vector<double> xs = x;
      double h = 1e-4 * params[i].scale;
      if (xs[i] + h > params[i].upper) h = -h;
      xs[i] += h;
      jac.col(i) = (stack(residual_of(xs)) - r) / (h / params[i].scale);
    }
    have_jac = true;
    const Eigen::MatrixXd a = jac.transpose() * jac;
    const Eigen::VectorXd g = jac.transpose() * r;
    bool accepted = false;
    while (lambda < 1e10) {
      Eigen::MatrixXd damped = a;
      for (int i = 0; i < p; ++i) damped(i, i) += lambda * std::max(a(i, i), 1e-12);
      const Eigen::VectorXd du = damped.ldlt().solve(-g);
      std::vector<double> xn = x;
      for (int i = 0; i < p; ++i) xn[i] = std::clamp(x[i] + du(i) * params[i].scale, params[i].lower, params[i].upper);
      if (xn == x) {
        lambda *= 10;
        continue;
      }
      const Eigen::VectorXd rn = stack(residual_of(xn));
      const double cn = rn.squaredNorm();
      if (cn < chi2) {
        const double gain = (chi2 - cn) / chi2;
        x = xn;
        r = rn;
        chi2 = cn;
        lambda = std::max(lambda / 4, 1e-9);
        accepted = true;
        if (gain < options.rel_tolerance) {
          res.converged = true;
          res.stop_reason = "relative improvement below tolerance";
        }
        break;
      }
      lambda *= 4;
    }
    if (!accepted) {
      res.converged = true;
      res.stop_reason = "no step reduces chi2";
      break;
    }
    if (res.converged) break;
    res.stop_reason = "iteration limit";
  }
  res.x = x;
  res.chi2 = chi2;
  res.sd.assign(params.size(), std::numeric_limits<double>::quiet_NaN());
  if (have_jac) {
    const double dof = std::max<double>(1.0, static_cast<double>(r.size()) - p);
    const Eigen::MatrixXd cov = (jac.transpose() * jac).ldlt().solve(Eigen::MatrixXd::Identity(p, p)) * (chi2 / dof);
    for (int i = 0; i < p; ++i) {
      const bool at_bound = x[i] <= params[i].lower || x[i] >= params[i].upper;
      if (!at_bound && cov(i, i) >= 0) res.sd[i] = std::sqrt(cov(i, i)) * params[i].scale;
    }
  }
  return res;
}

}  // namespace ambdiag
