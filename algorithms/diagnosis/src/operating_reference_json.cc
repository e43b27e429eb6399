// The operating reference as a JSON document (`ambdiag.operating_reference/1`),
// the file the server keeps per pump; reading checks every field and names
// the one that is wrong.
#include <cmath>

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/diagnosis/operating_reference.h"
#include "ambdiag/core/error.h"

namespace ambdiag {

namespace {

using nlohmann::json;
constexpr const char* kFormat = "ambdiag.operating_reference/1";

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw InputError("operating reference: " + path + ": " + what);
}

const json& field(const json& j, const std::string& key, const std::string& path) {
  if (!j.is_object()) fail(path, "must be an object");
  const auto it = j.find(key);
  if (it == j.end()) fail(path.empty() ? key : path + "." + key, "missing");
  return *it;
}

double number(const json& j, const std::string& path) {
  if (!j.is_number()) fail(path, "must be a number");
  const double x = j.get<double>();
  if (!std::isfinite(x)) fail(path, "must be finite");
  return x;
}

std::vector<double> numbers(const json& j, const std::string& path, size_t expected_size = SIZE_MAX) {
  if (!j.is_array()) fail(path, "must be an array of numbers");
  if (expected_size != SIZE_MAX && j.size() != expected_size)
    fail(path, "has " + std::to_string(j.size()) + " values, expected " + std::to_string(expected_size));
  std::vector<double> v;
  v.reserve(j.size());
  for (size_t i = 0; i < j.size(); ++i) v.push_back(number(j[i], path + "[" + std::to_string(i) + "]"));
  return v;
}

std::string text(const json& j, const std::string& path) {
  if (!j.is_string()) fail(path, "must be a string");
  return j.get<std::string>();
}

double positive(const json& j, const std::string& path) {
  const double x = number(j, path);
  if (!(x > 0.0)) fail(path, "must be > 0");
  return x;
}

}  // namespace

std::string operating_reference_to_json(const OperatingReference& r) {
  json runs = json::array();
  for (const auto& run : r.runs)
    runs.push_back({{"run_id", run.run_id}, {"speed_rpm", run.speed_rpm}, {"log_factor", run.log_factor}, {"chi2", run.chi2},
                    {"values", run.values}});
  json entries = json::array();
  for (const auto& e : r.entries) {
    std::vector<double> re, im;
    for (const auto& b : e.bias) re.push_back(b.real()), im.push_back(b.imag());
    entries.push_back({{"output", e.output}, {"input", e.input}, {"bias_re", re}, {"bias_im", im}, {"sigma2", e.sigma2},
                       {"kappa", e.kappa}, {"scatter_ratio", e.scatter_ratio}, {"scatter_p", e.scatter_p}});
  }
  const auto& o = r.options;
  const json doc = {{"format", kFormat},
                    {"options",
                     {{"common_sd_floor", o.common_sd_floor},
                      {"link_sd_floor", o.link_sd_floor},
                      {"log_factor_bound", o.log_factor_bound},
                      {"alpha_scatter", o.alpha_scatter},
                      {"passes", o.passes}}},
                    {"nuisance_links", r.nuisance_links},
                    {"log_factor_mean", r.log_factor_mean},
                    {"log_factor_mean_cov", r.log_factor_mean_cov},
                    {"common_sd", r.common_sd},
                    {"link_sd", r.link_sd},
                    {"common_sd_estimate", r.common_sd_estimate},
                    {"link_sd_estimate", r.link_sd_estimate},
                    {"sigma2_dof", r.sigma2_dof},
                    {"runs", runs},
                    {"freq_hz", r.freq_hz},
                    {"entries", entries}};
  return doc.dump();
}

OperatingReference operating_reference_from_json(const std::string& text_in) {
  json doc;
  try {
    doc = json::parse(text_in);
  } catch (const json::parse_error& e) {
    throw InputError(std::string("operating reference: invalid JSON: ") + e.what());
  }
  if (!doc.is_object()) fail("(document)", "must be an object");
  const std::string format = text(field(doc, "format", ""), "format");
  if (format != kFormat) fail("format", "'" + format + "', expected '" + kFormat + "'");

  OperatingReference r;
  const json& o = field(doc, "options", "");
  r.options.common_sd_floor = number(field(o, "common_sd_floor", "options"), "options.common_sd_floor");
  r.options.link_sd_floor = number(field(o, "link_sd_floor", "options"), "options.link_sd_floor");
  r.options.log_factor_bound = number(field(o, "log_factor_bound", "options"), "options.log_factor_bound");
  r.options.alpha_scatter = number(field(o, "alpha_scatter", "options"), "options.alpha_scatter");
  const json& passes = field(o, "passes", "options");
  if (!passes.is_number_integer()) fail("options.passes", "must be an integer");
  r.options.passes = passes.get<int>();
  std::string why;
  if (!r.options.is_valid(&why)) fail("options", why);

  const json& links = field(doc, "nuisance_links", "");
  if (!links.is_array()) fail("nuisance_links", "must be an array of link names");
  for (size_t i = 0; i < links.size(); ++i) r.nuisance_links.push_back(text(links[i], "nuisance_links[" + std::to_string(i) + "]"));
  const size_t k = r.nuisance_links.size();
  r.log_factor_mean = numbers(field(doc, "log_factor_mean", ""), "log_factor_mean", k);
  r.log_factor_mean_cov = numbers(field(doc, "log_factor_mean_cov", ""), "log_factor_mean_cov", k * k);
  r.common_sd_estimate = number(field(doc, "common_sd_estimate", ""), "common_sd_estimate");
  r.link_sd_estimate = number(field(doc, "link_sd_estimate", ""), "link_sd_estimate");
  r.sigma2_dof = number(field(doc, "sigma2_dof", ""), "sigma2_dof");
  if (r.sigma2_dof != 0.0 && !(r.sigma2_dof > 4.0)) fail("sigma2_dof", "must be 0 (exact) or > 4");
  if (k > 0) {
    r.common_sd = positive(field(doc, "common_sd", ""), "common_sd");
    r.link_sd = positive(field(doc, "link_sd", ""), "link_sd");
  }

  const json& runs = field(doc, "runs", "");
  if (!runs.is_array() || runs.size() < 2) fail("runs", "must be an array of at least 2 runs");
  for (size_t i = 0; i < runs.size(); ++i) {
    const std::string p = "runs[" + std::to_string(i) + "]";
    OperatingRun run;
    run.run_id = text(field(runs[i], "run_id", p), p + ".run_id");
    run.speed_rpm = number(field(runs[i], "speed_rpm", p), p + ".speed_rpm");
    if (run.speed_rpm < 0.0) fail(p + ".speed_rpm", "must be >= 0");
    run.log_factor = numbers(field(runs[i], "log_factor", p), p + ".log_factor", k);
    run.chi2 = number(field(runs[i], "chi2", p), p + ".chi2");
    const json& values = field(runs[i], "values", p);
    if (!values.is_number_integer()) fail(p + ".values", "must be an integer");
    run.values = values.get<int>();
    r.runs.push_back(std::move(run));
  }

  r.freq_hz = numbers(field(doc, "freq_hz", ""), "freq_hz");
  if (r.freq_hz.empty()) fail("freq_hz", "no lines");
  for (size_t l = 0; l < r.freq_hz.size(); ++l)
    if (!(r.freq_hz[l] > 0.0) || (l > 0 && !(r.freq_hz[l] > r.freq_hz[l - 1])))
      fail("freq_hz[" + std::to_string(l) + "]", "frequencies must be > 0 and strictly increasing");
  const size_t lines = r.freq_hz.size();
  const json& entries = field(doc, "entries", "");
  if (!entries.is_array() || entries.empty()) fail("entries", "must be a non-empty array");
  for (size_t i = 0; i < entries.size(); ++i) {
    const std::string p = "entries[" + std::to_string(i) + "]";
    OperatingEntry e;
    e.output = text(field(entries[i], "output", p), p + ".output");
    e.input = text(field(entries[i], "input", p), p + ".input");
    const auto re = numbers(field(entries[i], "bias_re", p), p + ".bias_re", lines);
    const auto im = numbers(field(entries[i], "bias_im", p), p + ".bias_im", lines);
    for (size_t l = 0; l < lines; ++l) e.bias.emplace_back(re[l], im[l]);
    e.sigma2 = numbers(field(entries[i], "sigma2", p), p + ".sigma2", lines);
    for (size_t l = 0; l < lines; ++l)
      if (!(e.sigma2[l] > 0.0)) fail(p + ".sigma2[" + std::to_string(l) + "]", "must be > 0");
    e.kappa = positive(field(entries[i], "kappa", p), p + ".kappa");
    e.scatter_ratio = number(field(entries[i], "scatter_ratio", p), p + ".scatter_ratio");
    e.scatter_p = number(field(entries[i], "scatter_p", p), p + ".scatter_p");
    if (r.find(e.output, e.input)) fail(p, "entry " + e.output + "/" + e.input + " repeated");
    r.entries.push_back(std::move(e));
  }
  return r;
}

}  // namespace ambdiag
