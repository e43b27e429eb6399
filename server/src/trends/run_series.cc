#include "trends/run_series.h"

#include <algorithm>
#include <cmath>

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;

std::optional<double> number_at(const json& j, const char* key) {
  if (!j.is_object()) return std::nullopt;
  const auto it = j.find(key);
  if (it == j.end() || !it->is_number()) return std::nullopt;
  const double v = it->get<double>();
  if (!std::isfinite(v)) return std::nullopt;
  return v;
}

void add(std::vector<SeriesValue>& out, std::string name, std::string unit, std::optional<double> value,
         std::optional<double> sd = std::nullopt) {
  if (!value) return;
  if (sd && !(std::isfinite(*sd) && *sd >= 0.0)) sd.reset();
  out.push_back({std::move(name), std::move(unit), *value, sd});
}

// Units of the fault parameters diagnosis reports (fault_models.h); the
// factors and ratios are dimensionless.
std::string fault_parameter_unit(const std::string& parameter) {
  if (parameter.size() > 2 && parameter.compare(parameter.size() - 2, 2, "_m") == 0) return "m";
  if (parameter.size() > 5 && parameter.compare(parameter.size() - 5, 5, "_kg_m") == 0) return "kg m";
  if (parameter.size() > 4 && parameter.compare(parameter.size() - 4, 4, "_rad") == 0) return "rad";
  return "1";
}

}  // namespace

std::vector<SeriesValue> run_series(const json& r) {
  std::vector<SeriesValue> out;
  if (!r.is_object()) return out;
  add(out, "run.speed_rpm", "rpm", number_at(r, "speed_rpm"));
  add(out, "fit.nrmse", "1", number_at(r, "nrmse"));

  if (const auto d = r.find("detection"); d != r.end() && d->is_object()) {
    add(out, "detection.ratio", "1", number_at(*d, "ratio"));
    add(out, "detection.p_value", "1", number_at(*d, "p_value"));
    if (const auto op = d->find("operating"); op != d->end() && op->is_object()) {
      if (const auto n = op->find("nuisance"); n != op->end() && n->is_array())
        for (const auto& link : *n) {
          if (!link.contains("link") || !link["link"].is_string()) continue;
          const auto factor = number_at(link, "factor");
          const auto log_sd = number_at(link, "sd");
          // sd of exp(x) to first order: factor * sd(x).
          add(out, "operating." + link["link"].get<std::string>() + ".factor", "1", factor,
              factor && log_sd ? std::optional<double>(*factor * *log_sd) : std::nullopt);
        }
    }
  }

  if (const auto modes = r.find("modes"); modes != r.end() && modes->is_array())
    for (const auto& m : *modes) {
      if (!m.contains("label") || !m["label"].is_string()) continue;
      const std::string base = "mode." + m["label"].get<std::string>();
      add(out, base + ".f_hz", "Hz", number_at(m, "f_hz"), number_at(m, "f_sd_hz"));
      add(out, base + ".zeta", "1", number_at(m, "zeta"), number_at(m, "zeta_sd"));
    }

  if (const auto dg = r.find("diagnosis"); dg != r.end() && dg->is_object())
    if (const auto faults = dg->find("faults"); faults != dg->end() && faults->is_array() && !faults->empty()) {
      const json& best = faults->front();
      const auto params = best.find("parameters");
      if (best.contains("fault") && best["fault"].is_string() && params != best.end() && params->is_object()) {
        const std::string base = "fault." + best["fault"].get<std::string>() + ".";
        for (const auto& [key, value] : params->items()) {
          const bool derived = (key.size() > 3 && key.compare(key.size() - 3, 3, "_sd") == 0) ||
                               (key.size() > 5 && key.compare(key.size() - 5, 5, "_ci95") == 0);
          if (derived || !value.is_number()) continue;
          add(out, base + key, fault_parameter_unit(key), number_at(*params, key.c_str()), number_at(*params, (key + "_sd").c_str()));
        }
      }
    }

  std::sort(out.begin(), out.end(), [](const SeriesValue& a, const SeriesValue& b) { return a.name < b.name; });
  return out;
}

}  // namespace ambdiag::server::detail
