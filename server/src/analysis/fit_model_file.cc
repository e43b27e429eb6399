#include "analysis/fit_model_file.h"

#include <cmath>
#include <complex>

#include "ambdiag/core/error.h"

namespace ambdiag::server::detail {

namespace {

using json = nlohmann::json;
using cd = std::complex<double>;
constexpr const char* kFormat = "ambdiag.fit_model/1";

json complex_json(cd v) { return json::array({v.real(), v.imag()}); }

const json& key(const json& j, const char* name, const std::string& where) {
  if (!j.is_object() || !j.contains(name)) throw InputError("fit_model.json: " + where + " has no '" + name + "'");
  return j.at(name);
}

double finite(const json& j, const std::string& what) {
  if (!j.is_number() || !std::isfinite(j.get<double>())) throw InputError("fit_model.json: " + what + " is not a finite number");
  return j.get<double>();
}

cd complex_of(const json& j, const std::string& what) {
  if (!j.is_array() || j.size() != 2) throw InputError("fit_model.json: " + what + " is not [re, im]");
  return {finite(j[0], what + "[0]"), finite(j[1], what + "[1]")};
}

}  // namespace

json fit_model_json(const RationalFitResult& fit, const FrfData& frf) {
  const RationalModel& m = fit.model;
  json poles = json::array();
  for (const cd& p : m.poles) poles.push_back(complex_json(p));
  json entries = json::array();
  for (size_t e = 0; e < fit.entries.size(); ++e) {
    const FrfEntry& fe = frf.entries.at(static_cast<size_t>(fit.entries[e]));
    json residues = json::array();
    for (Eigen::Index k = 0; k < m.residues.cols(); ++k)
      residues.push_back(complex_json(m.residues(static_cast<Eigen::Index>(e), k)));
    entries.push_back({{"output", fe.output},
                       {"input", fe.input},
                       {"direct", m.direct(static_cast<Eigen::Index>(e))},
                       {"residues", residues}});
  }
  return {{"format", kFormat},
          {"quantity", to_string(frf.quantity)},
          {"numerator_power", fit.numerator_power},
          {"delay_s", m.delay_s},
          {"poles_rad_per_s", poles},
          {"entries", entries}};
}

FrfData fit_frf_like(const json& model, const FrfData& grid) {
  if (key(model, "format", "the document") != kFormat)
    throw InputError(std::string("fit_model.json: format is not ") + kFormat);
  const json& power_j = key(model, "numerator_power", "the document");
  if (!power_j.is_number_integer() || power_j.get<int>() < 0 || power_j.get<int>() > 2)
    throw InputError("fit_model.json: numerator_power is not 0, 1 or 2");
  const int power = power_j.get<int>();
  RationalModel m;
  m.delay_s = finite(key(model, "delay_s", "the document"), "delay_s");
  const json& poles = key(model, "poles_rad_per_s", "the document");
  if (!poles.is_array()) throw InputError("fit_model.json: poles_rad_per_s is not an array");
  for (size_t k = 0; k < poles.size(); ++k) m.poles.push_back(complex_of(poles[k], "poles_rad_per_s[" + std::to_string(k) + "]"));
  const json& entries = key(model, "entries", "the document");
  if (!entries.is_array()) throw InputError("fit_model.json: entries is not an array");
  const auto n_entries = static_cast<Eigen::Index>(entries.size());
  const auto n_poles = static_cast<Eigen::Index>(m.poles.size());
  m.residues.resize(n_entries, n_poles);
  m.direct.resize(n_entries);
  FrfData out;
  out.quantity = grid.quantity;
  out.unit = grid.unit;
  out.speed_rpm = grid.speed_rpm;
  out.freq_hz = grid.freq_hz;
  for (Eigen::Index e = 0; e < n_entries; ++e) {
    const json& ej = entries[static_cast<size_t>(e)];
    const std::string where = "entries[" + std::to_string(e) + "]";
    const json& residues = key(ej, "residues", where);
    if (!residues.is_array() || static_cast<Eigen::Index>(residues.size()) != n_poles)
      throw InputError("fit_model.json: " + where + ".residues does not hold one value per pole");
    for (Eigen::Index k = 0; k < n_poles; ++k)
      m.residues(e, k) = complex_of(residues[static_cast<size_t>(k)], where + ".residues[" + std::to_string(k) + "]");
    m.direct(e) = finite(key(ej, "direct", where), where + ".direct");
    const json& output = key(ej, "output", where);
    const json& input = key(ej, "input", where);
    if (!output.is_string() || !input.is_string()) throw InputError("fit_model.json: " + where + " output or input is not a name");
    out.entries.push_back({output.get<std::string>(), input.get<std::string>(), {}, {}, {}});
  }
  for (Eigen::Index e = 0; e < n_entries; ++e) {
    auto& h = out.entries[static_cast<size_t>(e)].h;
    h.reserve(grid.freq_hz.size());
    for (const double f : grid.freq_hz) {
      const double w = 2 * M_PI * f;
      const cd scale = power == 0 ? cd(1.0) : std::pow(cd(0.0, w), power);
      h.push_back(m.evaluate(static_cast<int>(e), w) * scale);
    }
  }
  try {
    out.validate();  // no entry, or one repeated
  } catch (const InputError& e) {
    throw InputError(std::string("fit_model.json: ") + e.what());
  }
  return out;
}

}  // namespace ambdiag::server::detail
