#include "ambdiag/core/plant_model.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>

#include <nlohmann/json.hpp>

#include "ambdiag/core/error.h"
#include "ambdiag/core/io_util.h"
#include "json_fields.h"

namespace ambdiag {

using detail::JsonField;
using nlohmann::json;

namespace {

constexpr const char* kFormat = "ambdiag.plant/1";
// Refuse values no machine has; they are typos or unit errors (mm for m).
constexpr double kMaxLengthM = 100.0;
constexpr double kMaxDiameterM = 10.0;

std::string idx(const std::string& base, size_t i) { return base + "[" + std::to_string(i) + "]"; }

Material parse_material(const JsonField& f) {
  f.require_object();
  Material m;
  m.e_pa = f.at("E").positive();
  m.g_pa = f.at("G").positive();
  m.rho_kg_per_m3 = f.at("rho").positive();
  // Cowper's kappa uses nu = E/(2G) - 1; a real isotropic solid has -1 < nu < 0.5.
  const double nu = m.e_pa / (2.0 * m.g_pa) - 1.0;
  if (!(nu > -1.0 && nu < 0.5)) f.fail("E and G give Poisson's ratio " + std::to_string(nu) + ", must be in (-1, 0.5)");
  return m;
}

ShaftElement parse_element(const JsonField& f) {
  f.require_object();
  ShaftElement e;
  e.length_m = f.at("L").positive();
  if (e.length_m > kMaxLengthM) f.at("L").fail("must be <= 100 m");
  e.od_m = f.at("od").positive();
  if (e.od_m > kMaxDiameterM) f.at("od").fail("must be <= 10 m");
  e.id_m = f.has("id") ? f.at("id").non_negative() : 0.0;
  if (!(e.od_m > e.id_m)) f.at("od").fail("must be > id");
  e.material = f.at("material").string();
  if (auto a = f.opt("added_mass_per_m")) e.added_mass_kg_per_m = a->non_negative();
  return e;
}

int parse_node(const JsonField& f, int node_count) {
  const int64_t n = f.integer();
  if (n < 0 || n >= node_count) {
    f.fail("node " + std::to_string(n) + " does not exist (nodes 0.." + std::to_string(node_count - 1) + ")");
  }
  return static_cast<int>(n);
}

Disk parse_disk(const JsonField& f, int node_count) {
  f.require_object();
  Disk d;
  d.name = f.has("name") ? f.at("name").string() : "";
  d.node = parse_node(f.at("node"), node_count);
  d.m_kg = f.at("m").non_negative();
  d.id_kg_m2 = f.has("Id") ? f.at("Id").non_negative() : 0.0;
  d.ip_kg_m2 = f.has("Ip") ? f.at("Ip").non_negative() : 0.0;
  return d;
}

// Direct mass and stiffness terms of a link may not be negative: a negative
// direct mass makes the mass matrix indefinite (an unphysical model).
void check_link_coefficients(const JsonField& f, const std::array<std::optional<double>, kLinkCoefCount>& v) {
  for (LinkCoef c : {LinkCoef::mxx, LinkCoef::myy}) {
    const auto& x = v[static_cast<int>(c)];
    if (x && *x < 0.0) f.at(std::string(kLinkCoefNames[static_cast<int>(c)])).fail("must be >= 0 (negative mass)");
  }
}

std::array<std::optional<double>, kLinkCoefCount> parse_coefficients(const JsonField& f) {
  std::array<std::optional<double>, kLinkCoefCount> v;
  for (int i = 0; i < kLinkCoefCount; ++i) {
    const std::string key(kLinkCoefNames[static_cast<size_t>(i)]);
    if (auto c = f.opt(key)) v[static_cast<size_t>(i)] = c->number();
  }
  check_link_coefficients(f, v);
  return v;
}

Link parse_link(const JsonField& f, int node_count) {
  f.require_object();
  Link l;
  l.name = f.at("name").string();
  l.node = parse_node(f.at("node"), node_count);
  l.kind = f.has("kind") ? f.at("kind").string() : "";
  const auto top = parse_coefficients(f);
  for (int i = 0; i < kLinkCoefCount; ++i) l.coef[static_cast<size_t>(i)] = top[static_cast<size_t>(i)].value_or(0.0);
  if (auto t = f.opt("table")) {
    for (size_t r = 0; r < t->size(); ++r) {
      const JsonField row = t->at(r);
      row.require_object();
      LinkTableRow tr;
      tr.rpm = row.at("rpm").non_negative();
      if (!l.table.empty() && !(tr.rpm > l.table.back().rpm)) row.at("rpm").fail("must be greater than the previous row's rpm");
      tr.values = parse_coefficients(row);
      l.table.push_back(tr);
    }
  }
  return l;
}

Housing parse_housing(const JsonField& f) {
  f.require_object();
  Housing h;
  h.name = f.has("name") ? f.at("name").string() : "";
  h.plane = f.at("plane").string();
  const JsonField dirs = f.at("dirs");
  if (dirs.size() == 0) dirs.fail("must name at least one of x, y");
  for (size_t i = 0; i < dirs.size(); ++i) {
    const std::string d = dirs.at(i).string();
    if (d != "x" && d != "y") dirs.at(i).fail("must be \"x\" or \"y\"");
    if (std::find(h.dirs.begin(), h.dirs.end(), d) != h.dirs.end()) dirs.at(i).fail("repeats \"" + d + "\"");
    h.dirs.push_back(d);
  }
  h.f_hz = f.at("f_hz").positive();
  h.zeta = f.at("zeta").non_negative();
  h.m_kg = f.at("m").positive();
  return h;
}

AxialModel parse_axial(const JsonField& f) {
  f.require_object();
  AxialModel a;
  if (auto m = f.opt("m")) a.m_kg = m->positive();
  a.k_n_per_m = f.at("k").non_negative();
  a.c_ns_per_m = f.has("c") ? f.at("c").non_negative() : 0.0;
  if (auto hs = f.opt("housings")) {
    for (size_t i = 0; i < hs->size(); ++i) {
      const JsonField h = hs->at(i);
      h.require_object();
      AxialHousing ah;
      ah.name = h.has("name") ? h.at("name").string() : "";
      ah.f_hz = h.at("f_hz").positive();
      ah.zeta = h.at("zeta").non_negative();
      ah.m_kg = h.at("m").positive();
      a.housings.push_back(ah);
    }
  }
  return a;
}

MeasurementPoint parse_point(const JsonField& f, int node_count) {
  f.require_object();
  MeasurementPoint p;
  p.name = f.at("name").string();
  if (p.name.empty()) f.at("name").fail("must not be empty");
  p.plane = f.at("plane").string();
  const std::string dir = f.at("dir").string();
  if (dir != "x" && dir != "y" && dir != "z") f.at("dir").fail("must be \"x\", \"y\" or \"z\"");
  p.dir = dir[0];
  if (p.dir == 'z') {
    if (f.has("node")) parse_node(f.at("node"), node_count);  // allowed, ignored: axial points act on the axial model
  } else {
    p.node = parse_node(f.at("node"), node_count);
  }
  return p;
}

std::vector<MeasurementPoint> parse_points(const JsonField& root, const std::string& key, int node_count) {
  std::vector<MeasurementPoint> out;
  auto arr = root.opt(key);
  if (!arr) return out;
  std::set<std::string> names;
  for (size_t i = 0; i < arr->size(); ++i) {
    out.push_back(parse_point(arr->at(i), node_count));
    if (!names.insert(out.back().name).second) arr->at(i).at("name").fail("repeats \"" + out.back().name + "\"");
  }
  return out;
}

json coefficients_to_json(const std::array<std::optional<double>, kLinkCoefCount>& v, json j) {
  for (int i = 0; i < kLinkCoefCount; ++i) {
    if (v[static_cast<size_t>(i)]) j[std::string(kLinkCoefNames[static_cast<size_t>(i)])] = *v[static_cast<size_t>(i)];
  }
  return j;
}

}  // namespace

LinkCoefficients Link::at_speed(double rpm) const {
  LinkCoefficients out = coef;
  if (table.empty()) return out;
  for (int c = 0; c < kLinkCoefCount; ++c) {
    const auto ci = static_cast<size_t>(c);
    // Rows that give this coefficient; absent in every row keeps the top-level value.
    const LinkTableRow* lo = nullptr;
    const LinkTableRow* hi = nullptr;
    for (const auto& row : table) {
      if (!row.values[ci]) continue;
      if (row.rpm <= rpm) lo = &row;
      if (row.rpm >= rpm && !hi) hi = &row;
    }
    if (lo && hi && hi->rpm > lo->rpm) {
      const double t = (rpm - lo->rpm) / (hi->rpm - lo->rpm);
      out[ci] = *lo->values[ci] + t * (*hi->values[ci] - *lo->values[ci]);
    } else if (lo) {
      out[ci] = *lo->values[ci];
    } else if (hi) {
      out[ci] = *hi->values[ci];
    }
  }
  return out;
}

std::vector<double> PlantModel::node_positions_m() const {
  std::vector<double> z(shaft.size() + 1, 0.0);
  for (size_t i = 0; i < shaft.size(); ++i) z[i + 1] = z[i] + shaft[i].length_m;
  return z;
}

const MeasurementPoint* PlantModel::find_sensor(std::string_view n) const {
  for (const auto& s : sensors)
    if (s.name == n) return &s;
  return nullptr;
}

const MeasurementPoint* PlantModel::find_actuator(std::string_view n) const {
  for (const auto& a : actuators)
    if (a.name == n) return &a;
  return nullptr;
}

double PlantModel::rotor_mass_kg() const {
  double m = 0.0;
  for (const auto& e : shaft) {
    const Material& mat = materials.at(e.material);
    const double area = std::numbers::pi / 4.0 * (e.od_m * e.od_m - e.id_m * e.id_m);
    m += (mat.rho_kg_per_m3 * area + e.added_mass_kg_per_m) * e.length_m;
  }
  for (const auto& d : disks) m += d.m_kg;
  return m;
}

PlantModel plant_from_json(const json& doc) {
  const JsonField root(doc, "");
  root.require_object();
  if (!root.has("format")) throw InputError("format: missing (expected \"ambdiag.plant/1\")");
  if (root.at("format").string() != kFormat) {
    root.at("format").fail("is \"" + root.at("format").string() + "\", expected \"" + kFormat + "\"");
  }
  PlantModel p;
  p.name = root.has("name") ? root.at("name").string() : "";
  p.speed_rpm = root.has("speed_rpm") ? root.at("speed_rpm").non_negative() : 0.0;

  const JsonField mats = root.at("materials");
  mats.require_object();
  for (const auto& [key, value] : mats.raw().items()) p.materials[key] = parse_material(JsonField(value, "materials." + key));

  const JsonField shaft = root.at("shaft");
  if (shaft.size() == 0) shaft.fail("must have at least one element");
  for (size_t i = 0; i < shaft.size(); ++i) {
    p.shaft.push_back(parse_element(shaft.at(i)));
    if (!p.materials.count(p.shaft.back().material)) {
      shaft.at(i).at("material").fail("names unknown material \"" + p.shaft.back().material + "\"");
    }
  }
  const int nodes = p.node_count();

  if (auto d = root.opt("disks"))
    for (size_t i = 0; i < d->size(); ++i) p.disks.push_back(parse_disk(d->at(i), nodes));
  if (auto l = root.opt("links")) {
    std::set<std::string> names;
    for (size_t i = 0; i < l->size(); ++i) {
      p.links.push_back(parse_link(l->at(i), nodes));
      if (!names.insert(p.links.back().name).second) l->at(i).at("name").fail("repeats \"" + p.links.back().name + "\"");
    }
  }
  if (auto h = root.opt("housings"))
    for (size_t i = 0; i < h->size(); ++i) p.housings.push_back(parse_housing(h->at(i)));
  if (auto a = root.opt("axial")) p.axial = parse_axial(*a);

  if (auto sd = root.opt("structural_damping")) {
    const std::string kind = sd->at("kind").string();
    if (kind == "modal") {
      p.structural_damping.kind = StructuralDamping::Kind::modal;
      p.structural_damping.zeta = sd->at("zeta").non_negative();
      if (p.structural_damping.zeta >= 1.0) sd->at("zeta").fail("must be < 1");
    } else if (kind != "none") {
      sd->at("kind").fail("must be \"modal\" or \"none\"");
    }
  }
  if (auto red = root.opt("reduction")) {
    const std::string kind = red->at("kind").string();
    if (kind == "modal") {
      p.reduction.kind = Reduction::Kind::modal;
      const int64_t n = red->at("n_elastic_modes").integer();
      if (n < 0 || n > 4 * nodes) red->at("n_elastic_modes").fail("must be in 0.." + std::to_string(4 * nodes));
      p.reduction.n_elastic_modes = static_cast<int>(n);
    } else if (kind != "none") {
      red->at("kind").fail("must be \"modal\" or \"none\"");
    }
  }
  p.sensors = parse_points(root, "sensors", nodes);
  p.actuators = parse_points(root, "actuators", nodes);
  validate_plant(p);
  return p;
}

void validate_plant(const PlantModel& p) {
  auto fail = [](const std::string& what) { throw InputError(what); };
  if (p.shaft.empty()) fail("shaft: must have at least one element");
  if (!std::isfinite(p.speed_rpm) || p.speed_rpm < 0) fail("speed_rpm: must be >= 0");
  const int nodes = p.node_count();
  for (size_t i = 0; i < p.shaft.size(); ++i) {
    const auto& e = p.shaft[i];
    if (!(e.length_m > 0)) fail(idx("shaft", i) + ".L: must be > 0");
    if (!(e.od_m > e.id_m)) fail(idx("shaft", i) + ".od: must be > id");
    if (!(e.id_m >= 0)) fail(idx("shaft", i) + ".id: must be >= 0");
    if (!p.materials.count(e.material)) fail(idx("shaft", i) + ".material: unknown \"" + e.material + "\"");
  }
  for (size_t i = 0; i < p.disks.size(); ++i) {
    const auto& d = p.disks[i];
    if (d.node < 0 || d.node >= nodes) fail(idx("disks", i) + ".node: does not exist");
    if (!(d.m_kg >= 0 && d.id_kg_m2 >= 0 && d.ip_kg_m2 >= 0)) fail(idx("disks", i) + ": mass and inertias must be >= 0");
  }
  for (size_t i = 0; i < p.links.size(); ++i) {
    const auto& l = p.links[i];
    if (l.node < 0 || l.node >= nodes) fail(idx("links", i) + ".node: does not exist");
    for (double c : l.coef)
      if (!std::isfinite(c)) fail(idx("links", i) + ": coefficients must be finite");
  }
  if (p.axial) {
    if (p.axial->m_kg && !(*p.axial->m_kg > 0)) fail("axial.m: must be > 0");
    if (!(p.axial->k_n_per_m >= 0) || !(p.axial->c_ns_per_m >= 0)) fail("axial: k and c must be >= 0");
  }
  auto check_points = [&](const std::vector<MeasurementPoint>& pts, const std::string& key) {
    for (size_t i = 0; i < pts.size(); ++i) {
      const auto& pt = pts[i];
      if (pt.is_axial()) {
        if (!p.axial) fail(idx(key, i) + ": an axial point (dir z) needs the \"axial\" model");
      } else if (!pt.node || *pt.node < 0 || *pt.node >= nodes) {
        fail(idx(key, i) + ".node: does not exist");
      }
    }
  };
  check_points(p.sensors, "sensors");
  check_points(p.actuators, "actuators");
}

PlantModel read_plant_file(const std::string& path) {
  try {
    return plant_from_json(detail::parse_json_text(read_file_bytes(path), path));
  } catch (const InputError& e) {
    const std::string msg = e.what();
    if (msg.rfind(path, 0) == 0) throw;
    rethrow_with_context(e, path);
  }
}

json plant_to_json(const PlantModel& p) {
  json j;
  j["format"] = kFormat;
  j["name"] = p.name;
  j["speed_rpm"] = p.speed_rpm;
  j["materials"] = json::object();
  for (const auto& [name, m] : p.materials) j["materials"][name] = {{"E", m.e_pa}, {"G", m.g_pa}, {"rho", m.rho_kg_per_m3}};
  j["shaft"] = json::array();
  for (const auto& e : p.shaft) {
    json je = {{"L", e.length_m}, {"od", e.od_m}, {"id", e.id_m}, {"material", e.material}};
    if (e.added_mass_kg_per_m != 0.0) je["added_mass_per_m"] = e.added_mass_kg_per_m;
    j["shaft"].push_back(je);
  }
  j["disks"] = json::array();
  for (const auto& d : p.disks)
    j["disks"].push_back({{"name", d.name}, {"node", d.node}, {"m", d.m_kg}, {"Id", d.id_kg_m2}, {"Ip", d.ip_kg_m2}});
  j["links"] = json::array();
  for (const auto& l : p.links) {
    json jl = {{"name", l.name}, {"node", l.node}, {"kind", l.kind}};
    std::array<std::optional<double>, kLinkCoefCount> top;
    for (int i = 0; i < kLinkCoefCount; ++i)
      if (l.coef[static_cast<size_t>(i)] != 0.0) top[static_cast<size_t>(i)] = l.coef[static_cast<size_t>(i)];
    jl = coefficients_to_json(top, jl);
    if (!l.table.empty()) {
      jl["table"] = json::array();
      for (const auto& row : l.table) jl["table"].push_back(coefficients_to_json(row.values, {{"rpm", row.rpm}}));
    }
    j["links"].push_back(jl);
  }
  j["housings"] = json::array();
  for (const auto& h : p.housings)
    j["housings"].push_back(
        {{"name", h.name}, {"plane", h.plane}, {"dirs", h.dirs}, {"f_hz", h.f_hz}, {"zeta", h.zeta}, {"m", h.m_kg}});
  if (p.axial) {
    json ja = {{"m", p.axial->m_kg ? json(*p.axial->m_kg) : json(nullptr)},
               {"k", p.axial->k_n_per_m},
               {"c", p.axial->c_ns_per_m},
               {"housings", json::array()}};
    for (const auto& h : p.axial->housings)
      ja["housings"].push_back({{"name", h.name}, {"f_hz", h.f_hz}, {"zeta", h.zeta}, {"m", h.m_kg}});
    j["axial"] = ja;
  }
  if (p.structural_damping.kind == StructuralDamping::Kind::modal)
    j["structural_damping"] = {{"kind", "modal"}, {"zeta", p.structural_damping.zeta}};
  else
    j["structural_damping"] = {{"kind", "none"}};
  if (p.reduction.kind == Reduction::Kind::modal)
    j["reduction"] = {{"kind", "modal"}, {"n_elastic_modes", p.reduction.n_elastic_modes}};
  else
    j["reduction"] = {{"kind", "none"}};
  auto points = [](const std::vector<MeasurementPoint>& pts) {
    json a = json::array();
    for (const auto& pt : pts) {
      json jp = {{"name", pt.name}, {"plane", pt.plane}, {"dir", std::string(1, pt.dir)}};
      if (pt.node) jp["node"] = *pt.node;
      a.push_back(jp);
    }
    return a;
  };
  j["sensors"] = points(p.sensors);
  j["actuators"] = points(p.actuators);
  return j;
}

void write_plant_file(const std::string& path, const PlantModel& plant) {
  write_file_atomic(path, plant_to_json(plant).dump(2) + "\n");
}

}  // namespace ambdiag
