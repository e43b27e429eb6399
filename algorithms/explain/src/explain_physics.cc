// The candidate library of missing_physics.h: parameter updates within
// bounds and parameterised physics extensions of the plant model.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include "ambdiag/algorithms/explain/missing_physics.h"
#include "ambdiag/core/error.h"

namespace ambdiag {

namespace {

using nlohmann::json;

constexpr int idx(LinkCoef c) { return static_cast<int>(c); }

// Scales coefficients of a link, at top level and in its speed table.
void scale_link(Link& l, std::initializer_list<LinkCoef> coefs, double factor) {
  for (LinkCoef c : coefs) {
    l.coef[idx(c)] *= factor;
    for (auto& row : l.table)
      if (row.values[idx(c)]) *row.values[idx(c)] *= factor;
  }
}

// Adds to a coefficient at top level and in the table rows that state it.
void add_link(Link& l, LinkCoef c, double delta) {
  l.coef[idx(c)] += delta;
  for (auto& row : l.table)
    if (row.values[idx(c)]) *row.values[idx(c)] += delta;
}

std::string link_path(size_t i, std::string_view coef) { return "links[" + std::to_string(i) + "]." + std::string(coef); }

FitParameter factor_param(const std::string& name, double lo, double hi) { return {name, 1.0, lo, hi, 0.05}; }

// Candidate scaling coefficients of link i by one factor.
Candidate link_factor(const PlantModel& plant, size_t i, const std::vector<LinkCoef>& coefs, double lo, double hi,
                      const std::string& physics, const std::string& what) {
  const Link& l = plant.links[i];
  const double rpm = plant.speed_rpm;
  const LinkCoefficients at = l.at_speed(rpm);
  Candidate c;
  c.physics = physics;
  c.is_update = physics == "parameter_update";
  c.touches_rotor = true;
  c.id = physics + ":" + l.name + ":" + what;
  c.direction_key = "link_factor:" + l.name + ":" + what;
  c.location = {{"link", l.name}, {"node", l.node}};
  // A clearance factor c scales the coefficients by 1 / c: the parameter
  // is the coefficients' factor, not the clearance's.
  const std::string name = what == "clearance" ? "coefficient_factor" : what + "_factor";
  c.params = {factor_param(name, lo, hi)};
  const std::vector<LinkCoef> cs = coefs;
  c.apply = [i, cs](const std::vector<double>& x, PlantVariant& v) {
    for (LinkCoef k : cs) scale_link(v.plant.links[i], {k}, x[0]);
  };
  c.describe = [cs, at, name](const std::vector<double>& x) {
    json j = {{name, x[0]}};
    for (LinkCoef k : cs) j[std::string(kLinkCoefNames[idx(k)])] = at[idx(k)] * x[0];
    return j;
  };
  const LinkCoefficients top = l.coef;
  c.changes = [i, cs, top](const std::vector<double>& x) {
    std::vector<ParameterChange> ch;
    for (LinkCoef k : cs) ch.push_back({link_path(i, kLinkCoefNames[idx(k)]), top[idx(k)], top[idx(k)] * x[0]});
    return ch;
  };
  c.signature = what == "stiffness" ? "modes near the link shift in frequency"
                : what == "damping"   ? "peak heights of modes near the link change"
                                      : "modes near the seal shift and change height together: its clearance changed (every coefficient "
                                        "~ 1 / clearance)";
  return c;
}

bool link_has(const Link& l, std::initializer_list<LinkCoef> coefs) {
  for (LinkCoef c : coefs) {
    if (l.coef[idx(c)] != 0.0) return true;
    for (const auto& row : l.table)
      if (row.values[idx(c)] && *row.values[idx(c)] != 0.0) return true;
  }
  return false;
}

// Every coefficient a link states (at top level or in its table).
std::vector<LinkCoef> stated_coefficients(const Link& l) {
  std::vector<LinkCoef> out;
  for (int k = 0; k < kLinkCoefCount; ++k)
    if (link_has(l, {static_cast<LinkCoef>(k)})) out.push_back(static_cast<LinkCoef>(k));
  return out;
}

Candidate housing_update(const PlantModel& plant, size_t i, bool axial) {
  const double f = axial ? plant.axial->housings[i].f_hz : plant.housings[i].f_hz;
  const double z = axial ? plant.axial->housings[i].zeta : plant.housings[i].zeta;
  const double m = axial ? plant.axial->housings[i].m_kg : plant.housings[i].m_kg;
  const std::string base = axial ? "axial.housings[" + std::to_string(i) + "]" : "housings[" + std::to_string(i) + "]";
  Candidate c;
  c.physics = "parameter_update";
  c.is_update = true;
  c.id = "update:" + base;
  c.location = {{"housing", axial ? plant.axial->housings[i].name : plant.housings[i].name}};
  c.params = {{"f_factor", 1.0, 0.9, 1.1, 0.005}, {"zeta_factor", 1.0, 0.5, 2.0, 0.05}, {"m_factor", 1.0, 0.7, 1.3, 0.05}};
  c.apply = [i, axial](const std::vector<double>& x, PlantVariant& v) {
    auto set = [&](auto& h) {
      h.f_hz *= x[0];
      h.zeta *= x[1];
      h.m_kg *= x[2];
    };
    if (axial) set(v.plant.axial->housings[i]);
    else set(v.plant.housings[i]);
  };
  c.describe = [f, z, m](const std::vector<double>& x) { return json{{"f_hz", f * x[0]}, {"zeta", z * x[1]}, {"m", m * x[2]}}; };
  c.changes = [base, f, z, m](const std::vector<double>& x) {
    return std::vector<ParameterChange>{{base + ".f_hz", f, f * x[0]}, {base + ".zeta", z, z * x[1]}, {base + ".m", m, m * x[2]}};
  };
  c.signature = "an existing housing resonance shifted or damped differently";
  return c;
}

Candidate scalar_update(const std::string& path, double value, double lo, double hi, std::function<double&(PlantModel&)> ref,
                        const std::string& signature) {
  Candidate c;
  c.physics = "parameter_update";
  c.is_update = true;
  c.id = "update:" + path;
  c.location = {{"path", path}};
  c.params = {factor_param("factor", lo, hi)};
  c.apply = [ref](const std::vector<double>& x, PlantVariant& v) { ref(v.plant) *= x[0]; };
  c.describe = [path, value](const std::vector<double>& x) { return json{{path, value * x[0]}}; };
  c.changes = [path, value](const std::vector<double>& x) { return std::vector<ParameterChange>{{path, value, value * x[0]}}; };
  c.signature = signature;
  return c;
}

// Direct (same plane and direction) entries a housing of (plane, dirs) adds to.
bool housing_entry(const PlantModel& p, const FrfEntry& e, const std::string& plane, const std::string& dirs) {
  const MeasurementPoint* s = p.find_sensor(e.output);
  const MeasurementPoint* a = p.find_actuator(e.input);
  if (!s || !a) return false;
  if (plane == "Z") return s->is_axial() && a->is_axial();
  return !s->is_axial() && !a->is_axial() && s->plane == plane && a->plane == plane && s->dir == a->dir &&
         dirs.find(s->dir) != std::string::npos;
}

// Peaks of the weighted residual energy summed over a set of entries.
std::vector<int> residual_peaks(const ResidualView& view, const std::vector<size_t>& entries, int max_peaks) {
  const FrfData& m = *view.measured;
  const size_t n = m.freq_hz.size();
  std::vector<double> e(n, 0.0);
  for (size_t k : entries)
    for (size_t l = 0; l < n; ++l) e[l] += std::norm((view.model_h[k][l] - m.entries[k].h[l]) / view.sigma[k][l]);
  std::vector<double> s(n, 0.0);  // 5-line moving sum against single noisy lines
  for (size_t l = 0; l < n; ++l)
    for (size_t j = l >= 2 ? l - 2 : 0; j <= std::min(n - 1, l + 2); ++j) s[l] += e[j];
  std::vector<int> order(n);
  for (size_t l = 0; l < n; ++l) order[l] = static_cast<int>(l);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return s[static_cast<size_t>(a)] > s[static_cast<size_t>(b)]; });
  std::vector<int> peaks;
  for (int l : order) {
    if (static_cast<int>(peaks.size()) >= max_peaks) break;
    const double f = m.freq_hz[static_cast<size_t>(l)];
    bool near = false;
    for (int p : peaks) near |= std::abs(m.freq_hz[static_cast<size_t>(p)] - f) < 0.05 * f + 3.0;
    if (!near) peaks.push_back(l);
  }
  return peaks;
}

Candidate housing_mode(const ResidualView& view, const std::string& plane, const std::string& dirs,
                       const std::vector<size_t>& entries, int peak) {
  const FrfData& m = *view.measured;
  const double f0 = m.freq_hz[static_cast<size_t>(peak)];
  const double w0 = 2 * M_PI * f0;
  double d = 0.0;
  for (size_t k : entries) d += std::abs(m.entries[k].h[static_cast<size_t>(peak)] - view.model_h[k][static_cast<size_t>(peak)]);
  d = std::max(d / static_cast<double>(entries.size()), 1e-30);
  const double z0 = 0.03;
  const double m0 = 1.0 / (d * w0 * w0 * 2 * z0);
  Candidate c;
  c.physics = "housing_mode";
  c.touches_rotor = false;
  char buf[64];
  std::snprintf(buf, sizeof buf, "@%.0f", f0);
  c.id = "housing_mode:" + plane + ":" + dirs + buf;
  json jd = json::array();
  if (plane == "Z") jd.push_back("z");
  else
    for (char ch : dirs) jd.push_back(std::string(1, ch));
  c.location = {{"plane", plane}, {"dirs", jd}};
  const double fmin = m.freq_hz.front(), fmax = m.freq_hz.back();
  c.params = {{"f_hz", f0, fmin, fmax, 0.005 * f0}, {"zeta", z0, 0.002, 0.6, 0.005}, {"m", m0, m0 * 1e-3, m0 * 1e3, 0.1 * m0}};
  c.apply = [plane, dirs](const std::vector<double>& x, PlantVariant& v) {
    // Named after the fitted frequency, not the residual peak it started at.
    const std::string name =
        (plane == "Z" ? "housing_axial_" : "housing_" + plane + "_") + std::to_string(static_cast<int>(std::lround(x[0]))) + "Hz";
    if (plane == "Z") {
      v.plant.axial->housings.push_back({name, x[0], x[1], x[2]});
    } else {
      Housing h{name, plane, {}, x[0], x[1], x[2]};
      for (char ch : dirs) h.dirs.push_back(std::string(1, ch));
      v.plant.housings.push_back(h);
    }
  };
  c.describe = [](const std::vector<double>& x) { return json{{"f_hz", x[0]}, {"zeta", x[1]}, {"m", x[2]}}; };
  c.signature = plane == "Z" ? "a resonance in the axial FRF (xZ/fZ) that the axial rotor model lacks"
                             : "a resonance in the direct FRFs of plane " + plane + " (" + dirs + ") only, no rotor mode behind it";
  return c;
}

Candidate delay_candidate(const ResidualView& view) {
  // Start at the weighted phase slope of H_meas / H_model.
  const FrfData& m = *view.measured;
  double num = 0.0, den = 0.0;
  for (size_t k = 0; k < m.entries.size(); ++k) {
    for (size_t l = 0; l < m.freq_hz.size(); ++l) {
      const auto hm = view.model_h[k][l];
      if (std::abs(hm) == 0.0) continue;
      const double wgt = std::norm(hm) / (view.sigma[k][l] * view.sigma[k][l]);
      const double w = 2 * M_PI * m.freq_hz[l];
      const double ph = std::arg(m.entries[k].h[l] / hm);
      num += wgt * w * ph;
      den += wgt * w * w;
    }
  }
  const double tau0 = den > 0 ? std::clamp(-num / den, -1e-3, 1e-3) : 0.0;
  Candidate c;
  c.physics = "acquisition_delay";
  c.id = "acquisition_delay";
  c.location = {{"channels", "all"}};
  c.params = {{"seconds", tau0, -2e-3, 2e-3, 1e-6}};
  c.apply = [](const std::vector<double>& x, PlantVariant& v) { v.delay_s += x[0]; };
  c.describe = [](const std::vector<double>& x) { return json{{"seconds", x[0]}, {"delay_us", x[0] * 1e6}}; };
  c.signature = "phase of every FRF drifts linearly with frequency (-w tau), magnitudes unchanged";
  return c;
}

Candidate cross_coupling(const PlantModel& plant, size_t i) {
  const Link& l = plant.links[i];
  const LinkCoefficients at = l.at_speed(plant.speed_rpm);
  const double kref = std::max(std::abs(at[idx(LinkCoef::kxx)]), 1e4);
  const double cref = std::max(std::abs(at[idx(LinkCoef::cxx)]), 10.0);
  Candidate c;
  c.physics = "seal_cross_coupling";
  c.touches_rotor = true;
  c.id = "seal_cross_coupling:" + l.name;
  c.location = {{"link", l.name}, {"node", l.node}};
  c.params = {{"k", 0.0, -3 * kref, 3 * kref, 0.05 * kref}, {"c", 0.0, -3 * cref, 3 * cref, 0.05 * cref}};
  c.apply = [i](const std::vector<double>& x, PlantVariant& v) {
    Link& lk = v.plant.links[i];
    add_link(lk, LinkCoef::kxy, x[0]);
    add_link(lk, LinkCoef::kyx, -x[0]);
    add_link(lk, LinkCoef::cxy, x[1]);
    add_link(lk, LinkCoef::cyx, -x[1]);
  };
  c.describe = [kref, cref](const std::vector<double>& x) {
    return json{{"k", x[0]}, {"c", x[1]}, {"k_over_direct_k", x[0] / kref}, {"c_over_direct_c", x[1] / cref}};
  };
  c.signature = "non-reciprocal cross FRFs (Hxy != Hyx of one plane), forward whirl less damped than backward";
  return c;
}

Candidate added_mass(const PlantModel& plant, int node) {
  const double mr = plant.rotor_mass_kg();
  const double ms = 0.02 * mr;
  Candidate c;
  c.physics = "added_mass";
  c.touches_rotor = true;
  c.id = "added_mass:node" + std::to_string(node);
  c.location = {{"node", node}};
  // Ip: zero for fluid that does not spin with the shaft, up to 2 Id for a
  // part that does (a heavier impeller, a balancing disk): left to the fit,
  // so that a spinning mass needs no gyroscopic change beside it.
  c.params = {{"kg", 0.0, 0.0, 0.5 * mr, ms}, {"Id", 0.0, 0.0, 0.5 * mr * 0.01, ms * 0.002}, {"Ip", 0.0, 0.0, 1.1 * mr * 0.01, ms * 0.004}};
  c.apply = [node](const std::vector<double>& x, PlantVariant& v) {
    v.plant.disks.push_back({"added_mass_node" + std::to_string(node), node, x[0], x[1], x[2]});
  };
  c.describe = [](const std::vector<double>& x) { return json{{"kg", x[0]}, {"Id", x[1]}, {"Ip", x[2]}}; };
  c.signature = "modes with motion at the node lowered in frequency (fluid or attached inertia)";
  return c;
}

Candidate noncollocation(const PlantModel& plant, const std::string& plane, int offset) {
  std::vector<size_t> sensors;
  int node = -1;
  for (size_t k = 0; k < plant.sensors.size(); ++k) {
    if (plant.sensors[k].plane == plane && !plant.sensors[k].is_axial() && plant.sensors[k].node) {
      sensors.push_back(k);
      node = *plant.sensors[k].node;
    }
  }
  Candidate c;
  c.physics = "sensor_noncollocation";
  c.touches_rotor = true;
  c.id = "sensor_noncollocation:" + plane + ":" + std::to_string(offset);
  const auto pos = plant.node_positions_m();
  const int to = node + offset;
  if (sensors.empty() || to < 0 || to >= plant.node_count()) return {};
  c.location = {{"plane", plane}, {"node_from", node}, {"node_to", to}};
  c.apply = [sensors, offset](const std::vector<double>&, PlantVariant& v) {
    for (size_t k : sensors) *v.plant.sensors[k].node += offset;
  };
  const double dz = pos[static_cast<size_t>(to)] - pos[static_cast<size_t>(node)];
  c.describe = [dz, node, to](const std::vector<double>&) { return json{{"offset_m", dz}, {"node_from", node}, {"node_to", to}}; };
  c.signature = "anti-resonances of the plane's FRFs move while the resonances stay";
  return c;
}

// The gyroscopic effect of the disks. Where the model states polar
// inertias, one factor scales them all (Ip = (1 + g) Ip0). Where it states
// none (every Ip zero: the effect left out), each disk gets its own Ip in
// [0, 2.2 Id]: a body of revolution has Ip <= 2 Id (a thin disk reaches
// it), and one common ratio to Id would leave a pattern that other physics
// would be called in to cover.
Candidate gyroscopic(const PlantModel& plant) {
  bool all_zero = true;
  for (const auto& d : plant.disks) all_zero = all_zero && d.ip_kg_m2 == 0.0;
  Candidate c;
  c.physics = "gyroscopic";
  c.touches_rotor = true;
  c.id = "gyroscopic";
  c.location = {{"disks", "all"}};
  if (!all_zero) {
    c.params = {{"Ip_change", 0.0, -1.0, 3.0, 0.05}};
    c.apply = [](const std::vector<double>& x, PlantVariant& v) {
      for (auto& d : v.plant.disks) d.ip_kg_m2 *= 1.0 + x[0];
    };
    c.describe = [](const std::vector<double>& x) { return json{{"Ip_factor", 1.0 + x[0]}}; };
    c.signature = "forward/backward whirl split of the modes changes";
    return c;
  }
  std::vector<std::string> names;
  for (size_t k = 0; k < plant.disks.size(); ++k) {
    const Disk& d = plant.disks[k];
    const double top = 2.2 * std::max(d.id_kg_m2, 1e-9);
    names.push_back(d.name.empty() ? "disk" + std::to_string(k) : d.name);
    c.params.push_back({"Ip:" + names.back(), 0.0, 0.0, top, 0.05 * top});
  }
  c.apply = [](const std::vector<double>& x, PlantVariant& v) {
    for (size_t k = 0; k < v.plant.disks.size() && k < x.size(); ++k) v.plant.disks[k].ip_kg_m2 += x[k];
  };
  c.describe = [names](const std::vector<double>& x) {
    json ip = json::object();
    double total = 0.0;
    for (size_t k = 0; k < x.size(); ++k) ip[names[k]] = x[k], total += x[k];
    return json{{"Ip_kg_m2", ip}, {"Ip_total_kg_m2", total}};
  };
  c.signature = "forward and backward whirl of each mode split apart, damping unchanged (disk polar inertia the model left out)";
  return c;
}

bool has_link(const PlantModel& plant, int node) {
  for (const auto& l : plant.links)
    if (l.node == node) return true;
  return false;
}

// A new link to ground at a node: kxx = kyy = k, cxx = cyy = c, up to ten
// times the model's stiffest and most damped link.
Candidate node_support(const PlantModel& plant, int node) {
  double kref = 1e5, cref = 100.0;
  for (const auto& l : plant.links) {
    const LinkCoefficients at = l.at_speed(plant.speed_rpm);
    kref = std::max({kref, std::abs(at[idx(LinkCoef::kxx)]), std::abs(at[idx(LinkCoef::kyy)])});
    cref = std::max({cref, std::abs(at[idx(LinkCoef::cxx)]), std::abs(at[idx(LinkCoef::cyy)])});
  }
  Candidate c;
  c.physics = "coupling_stiffness";
  c.touches_rotor = true;
  c.id = "coupling_stiffness:node" + std::to_string(node);
  c.location = {{"node", node}, {"link", "none in the model"}};
  c.params = {{"k", 0.0, 0.0, 10.0 * kref, 0.02 * kref}, {"c", 0.0, 0.0, 10.0 * cref, 0.02 * cref}};
  c.screen_params = 1;
  c.apply = [node](const std::vector<double>& x, PlantVariant& v) {
    if (x[0] == 0.0 && x[1] == 0.0) return;  // neutral: the model as it is
    Link l;
    l.name = "support_node" + std::to_string(node);
    l.kind = "coupling";
    l.node = node;
    l.coef[idx(LinkCoef::kxx)] = l.coef[idx(LinkCoef::kyy)] = x[0];
    l.coef[idx(LinkCoef::cxx)] = l.coef[idx(LinkCoef::cyy)] = x[1];
    v.plant.links.push_back(std::move(l));
  };
  c.describe = [](const std::vector<double>& x) { return json{{"k", x[0]}, {"c", x[1]}}; };
  c.signature = "modes with motion at the node stiffened (a coupling or support to ground the model lacks)";
  return c;
}

}  // namespace

std::vector<Candidate> update_candidates(const PlantModel& plant) {
  std::vector<Candidate> out;
  for (size_t i = 0; i < plant.links.size(); ++i) {
    const Link& l = plant.links[i];
    if (link_has(l, {LinkCoef::kxx, LinkCoef::kyy}))
      out.push_back(link_factor(plant, i, {LinkCoef::kxx, LinkCoef::kyy}, 0.7, 1.3, "parameter_update", "stiffness"));
    if (link_has(l, {LinkCoef::cxx, LinkCoef::cyy}))
      out.push_back(link_factor(plant, i, {LinkCoef::cxx, LinkCoef::cyy}, 0.5, 2.0, "parameter_update", "damping"));
    // A fluid seal's clearance: its bulk-flow coefficients, direct and
    // cross-coupled K, C and M, all fall as 1 / clearance (the wear law of
    // algorithms/diagnosis/fault_models.h). Worn (a balance piston at 1.5 x
    // its clearance) loses a third of its stiffness, damping, cross-coupling
    // and fluid mass at once; no factor on the direct terms alone, nor any
    // physics, expresses the lost mass.
    if (l.kind == "seal" || l.kind == "balance_piston")
      out.push_back(link_factor(plant, i, stated_coefficients(l), 0.5, 2.0, "parameter_update", "clearance"));
  }
  for (size_t i = 0; i < plant.disks.size(); ++i) {
    const Disk& d = plant.disks[i];
    Candidate c;
    c.physics = "parameter_update";
    c.is_update = true;
    c.touches_rotor = true;
    c.id = "update:disks[" + std::to_string(i) + "]";
    c.location = {{"disk", d.name}, {"node", d.node}};
    c.params = {factor_param("mass_factor", 0.9, 1.1)};
    c.apply = [i](const std::vector<double>& x, PlantVariant& v) {
      v.plant.disks[i].m_kg *= x[0];
      v.plant.disks[i].id_kg_m2 *= x[0];
    };
    const double m = d.m_kg, id = d.id_kg_m2;
    c.describe = [m, id](const std::vector<double>& x) { return json{{"m", m * x[0]}, {"Id", id * x[0]}}; };
    const std::string base = "disks[" + std::to_string(i) + "]";
    c.changes = [base, m, id](const std::vector<double>& x) {
      return std::vector<ParameterChange>{{base + ".m", m, m * x[0]}, {base + ".Id", id, id * x[0]}};
    };
    c.signature = "modes with motion at the disk shift a little";
    out.push_back(c);
  }
  for (size_t i = 0; i < plant.housings.size(); ++i) out.push_back(housing_update(plant, i, false));
  if (plant.axial) {
    for (size_t i = 0; i < plant.axial->housings.size(); ++i) out.push_back(housing_update(plant, i, true));
    out.push_back(scalar_update("axial.k", plant.axial->k_n_per_m, 0.7, 1.3,
                                [](PlantModel& p) -> double& { return p.axial->k_n_per_m; }, "the axial rotor mode shifts"));
    out.push_back(scalar_update("axial.c", plant.axial->c_ns_per_m, 1.0 / 3.0, 3.0,
                                [](PlantModel& p) -> double& { return p.axial->c_ns_per_m; }, "the axial rotor mode is damped differently"));
  }
  if (plant.structural_damping.kind == StructuralDamping::Kind::modal && plant.structural_damping.zeta > 0) {
    Candidate c = scalar_update("structural_damping.zeta", plant.structural_damping.zeta, 0.5, 2.0,
                                [](PlantModel& p) -> double& { return p.structural_damping.zeta; }, "bending-mode peaks change height");
    c.touches_rotor = true;
    out.push_back(c);
  }
  return out;
}

std::vector<Candidate> physics_candidates(const PlantModel& plant, const ResidualView& view) {
  std::vector<Candidate> out;
  const FrfData& m = *view.measured;
  // Housing modes: per plane and direction set, started at the residual's peaks.
  std::set<std::string> planes;
  for (const auto& s : plant.sensors) planes.insert(s.is_axial() ? "Z" : s.plane);
  for (const auto& plane : planes) {
    if (plane == "Z" && !plant.axial) continue;
    for (const std::string dirs : {"xy", "x", "y"}) {
      if (plane == "Z" && dirs != "xy") continue;
      std::vector<size_t> entries;
      for (size_t k = 0; k < m.entries.size(); ++k)
        if (housing_entry(plant, m.entries[k], plane, dirs)) entries.push_back(k);
      if (entries.empty()) continue;
      for (int peak : residual_peaks(view, entries, 3)) out.push_back(housing_mode(view, plane, dirs, entries, peak));
    }
  }
  out.push_back(delay_candidate(view));
  for (size_t i = 0; i < plant.links.size(); ++i) {
    out.push_back(cross_coupling(plant, i));
    const Link& l = plant.links[i];
    const bool coupling = l.kind == "coupling";
    if (link_has(l, {LinkCoef::kxx, LinkCoef::kyy}))
      out.push_back(link_factor(plant, i, {LinkCoef::kxx, LinkCoef::kyy}, 0.1, 10.0, coupling ? "coupling_stiffness" : "stiffness_change",
                                "stiffness"));
    if (link_has(l, {LinkCoef::cxx, LinkCoef::cyy}))
      out.push_back(link_factor(plant, i, {LinkCoef::cxx, LinkCoef::cyy}, 0.1, 10.0, "damping", "damping"));
  }
  for (int n = 0; n < plant.node_count(); ++n) out.push_back(added_mass(plant, n));
  for (const auto& plane : planes) {
    if (plane == "Z") continue;
    for (int off : {-2, -1, 1, 2}) {
      Candidate c = noncollocation(plant, plane, off);
      if (c.apply) out.push_back(std::move(c));
    }
  }
  if (!plant.disks.empty()) out.push_back(gyroscopic(plant));
  // A stiffness to ground where the model has no link at all (a coupling or
  // support it lacks, e.g. the drive-end coupling left out): every node.
  for (int n = 0; n < plant.node_count(); ++n)
    if (!has_link(plant, n)) out.push_back(node_support(plant, n));
  // Structural damping beyond its update bounds is not offered: the update
  // covers it and a second factor would only compound with it.
  return out;
}

Candidate resonant_attachment(const PlantModel& plant, int node, double f_lo_hz, double f_hi_hz) {
  const double mr = plant.rotor_mass_kg();
  Candidate c;
  c.physics = "resonant_attachment";
  c.touches_rotor = true;
  c.id = "resonant_attachment:node" + std::to_string(node);
  c.location = {{"node", node}, {"z_m", plant.node_positions_m()[static_cast<size_t>(node)]}};
  const double f0 = std::sqrt(f_lo_hz * f_hi_hz);
  c.params = {{"f_hz", f0, f_lo_hz, f_hi_hz, 0.01 * f0}, {"zeta", 0.02, 0.001, 0.3, 0.005}, {"kg", 0.02 * mr, 1e-4 * mr, 0.5 * mr, 0.005 * mr}};
  c.impedance_node = node;
  c.node_impedance = [](double w, const std::vector<double>& x) {
    const double wn = 2.0 * M_PI * x[0];
    const std::complex<double> kc(x[2] * wn * wn, w * 2.0 * x[1] * x[2] * wn);
    return -w * w * x[2] * kc / (kc - w * w * x[2]);
  };
  c.apply = [](const std::vector<double>&, PlantVariant&) {};
  c.describe = [](const std::vector<double>& x) { return json{{"f_hz", x[0]}, {"zeta", x[1]}, {"kg", x[2]}}; };
  c.signature = "an extra mode of its own, seen on every lateral entry, at a place on the rotor";
  return c;
}

std::vector<Candidate> neighbour_candidates(const PlantModel& plant, const Candidate& c) {
  std::vector<Candidate> out;
  if (c.physics == "added_mass") {
    const int node = c.location["node"].get<int>();
    for (int n : {node - 2, node - 1, node + 1, node + 2})
      if (n >= 0 && n < plant.node_count()) out.push_back(added_mass(plant, n));
  }
  // A new support: a neighbouring node without a link (the screen cannot
  // tell a large stiffness at the shaft end from one a node further in).
  if (c.physics == "coupling_stiffness" && c.location.value("link", std::string()) == "none in the model") {
    const int node = c.location["node"].get<int>();
    for (int n : {node - 2, node - 1, node + 1, node + 2})
      if (n >= 0 && n < plant.node_count() && !has_link(plant, n)) out.push_back(node_support(plant, n));
  }
  return out;
}

json variant_to_json(const PlantVariant& v) {
  json j = plant_to_json(v.plant);
  if (v.delay_s != 0.0) j["acquisition"] = {{"delay_s", v.delay_s}, {"note", "every FRF of this machine is measured as H exp(-j w delay_s)"}};
  return j;
}

PlantVariant variant_from_json(const json& doc) {
  PlantVariant v{plant_from_json(doc), 0.0};
  if (doc.is_object() && doc.contains("acquisition")) {
    const json& a = doc["acquisition"];
    if (!a.is_object() || !a.contains("delay_s") || !a["delay_s"].is_number() || !std::isfinite(a["delay_s"].get<double>()))
      throw InputError("acquisition.delay_s: must be a finite number (seconds)");
    v.delay_s = a["delay_s"].get<double>();
  }
  return v;
}

}  // namespace ambdiag
