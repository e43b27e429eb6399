#include "ambdiag/algorithms/diagnosis/diagnosis_report.h"

#include <cmath>

namespace ambdiag {

namespace {

using nlohmann::json;

json symptom_json(const Symptom& s) {
  json j = {{"kind", s.kind}};
  if (s.kind == "entry") {
    j.update({{"output", s.output}, {"input", s.input}, {"chi2", s.statistic}, {"dof", s.dof}, {"p_value", s.p_value}});
  } else if (s.kind == "sensor_row") {
    j.update({{"sensor", s.output}, {"share_of_change", s.statistic}});
  } else if (s.kind == "actuator_column") {
    j.update({{"actuator", s.input}, {"share_of_change", s.statistic}});
  } else if (s.kind == "band") {
    j.update({{"band_hz", {s.band_lo_hz, s.band_hi_hz}}, {"share_of_change", s.statistic}});
  }
  return j;
}

json fault_json(const FaultEstimate& f, const PlantModel& plant) {
  json j = {{"fault", f.name}, {"score", f.score}};
  if (f.name == "unknown") {
    j["parameters"] = json::object();
    j["reason"] = "no fault model brings the residual to the noise floor";
    return j;
  }
  const auto& h = f.hypothesis;
  json p = {{h.parameter, f.value}, {h.parameter + "_sd", f.sd}, {h.parameter + "_ci95", {f.ci_lo, f.ci_hi}}};
  if (!h.links.empty()) p["coefficient_factor"] = f.coefficient_factor;
  j["parameters"] = p;
  json loc = json::object();
  if (!h.elements.empty()) {
    if (h.elements.size() == 1) loc["element"] = h.elements.front();
    else loc["elements"] = h.elements;
    loc["z_m"] = {f.z_lo_m, f.z_hi_m};
  }
  if (!h.links.empty()) {
    json names = json::array();
    for (int i : h.links) names.push_back(plant.links[static_cast<size_t>(i)].name);
    loc["links"] = names;
  }
  if (h.kind == FaultKind::sensor_fault) loc["sensor"] = h.channel;
  if (h.kind == FaultKind::actuator_fault) loc["actuator"] = h.channel;
  if (!loc.empty()) j["location"] = loc;
  j.update({{"chi2", f.chi2}, {"bic", f.bic}, {"nrmse", f.nrmse}});
  return j;
}

}  // namespace

json diagnosis_to_json(const DiagnosisResult& r, const PlantModel& plant) {
  json out = {{"detected", r.detected},    {"statistic", r.statistic}, {"threshold", r.threshold},
              {"dof", r.dof},              {"p_value", r.p_value},     {"alpha", r.alpha},
              {"isolation", r.isolation},  {"explained", r.explained}, {"symptoms", json::array()},
              {"faults", json::array()}};
  for (const auto& s : r.symptoms) out["symptoms"].push_back(symptom_json(s));
  for (const auto& f : r.faults) out["faults"].push_back(fault_json(f, plant));
  out["fit"] = {{"nrmse_before", r.nrmse_before},
                {"nrmse_after", r.nrmse_after},
                {"chi2_before", r.chi2_before},
                {"chi2_after", r.chi2_after},
                {"values", (r.operating.used ? r.operating.residual_dof : r.dof) / 2}};
  out["not_assessed"] = json::array();
  for (const auto& s : r.not_assessed) {
    const auto colon = s.find(':');
    out["not_assessed"].push_back({{"fault", s.substr(0, colon)}, {"reason", colon == std::string::npos ? "" : s.substr(colon + 2)}});
  }
  // Detection under operating conditions (operating_reference.h): the run's
  // speed, both tests and the seal drift fitted.
  if (r.operating.used) out["operating"] = operating_tests_to_json(r.operating);
  return out;
}

json operating_tests_to_json(const OperatingTests& t) {
  json nuisance = json::array();
  for (const auto& n : t.nuisance)
    nuisance.push_back(
        {{"link", n.link}, {"log_factor", n.log_factor}, {"factor", std::exp(n.log_factor)}, {"sd", n.sd}, {"normal_sd", n.normal_sd}});
  return {{"speed_rpm", t.speed_rpm},
          {"alpha_each", t.alpha_each},
          {"residual",
           {{"statistic", t.residual_statistic},
            {"threshold", t.residual_threshold},
            {"dof", t.residual_dof},
            {"p_value", t.residual_p_value},
            {"detected", t.residual_detected}}},
          {"drift",
           {{"statistic", t.drift_statistic},
            {"threshold", t.drift_threshold},
            {"dof", t.drift_dof},
            {"p_value", t.drift_p_value},
            {"detected", t.drift_detected}}},
          {"nuisance", nuisance}};
}

}  // namespace ambdiag
