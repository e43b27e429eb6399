#include "explain_speeds.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/core/error.h"
#include "explain_locate.h"

namespace ambdiag::detail {

OtherSpeeds::OtherSpeeds(const std::vector<FrfData>& recordings, double primary_rpm) : primary_rpm_(primary_rpm) {
  for (size_t k = 0; k < recordings.size(); ++k) {
    const auto& r = recordings[k];
    const auto run_id = r.meta("run_id");
    const std::string which = "recording " + std::to_string(k + 2) + (run_id ? " (" + *run_id + ")" : "");
    if (!r.speed_rpm || !(*r.speed_rpm > 0.0))
      throw InputError(which + ": speed_rpm: a recording at another speed must state its speed (> 0)");
    // Equal speeds add noise averaging, not a speed law: refused so that a
    // repeated file is not taken for evidence it is not.
    if (std::abs(*r.speed_rpm - primary_rpm) <= 1e-3 * primary_rpm)
      throw InputError(which + ": speed_rpm: " + std::to_string(*r.speed_rpm) + " is the first recording's speed, not another one");
    evals_.emplace_back(r);
  }
}

double OtherSpeeds::values() const {
  double n = 0.0;
  for (const auto& e : evals_) n += 2.0 * static_cast<double>(e.measured().entries.size() * e.measured().freq_hz.size());
  return n;
}

std::vector<std::complex<double>> OtherSpeeds::residual(const std::function<PlantVariant(double scale)>& build, double exponent) {
  std::vector<std::complex<double>> out;
  for (auto& e : evals_) {
    std::vector<int> lines(e.measured().freq_hz.size());
    for (size_t l = 0; l < lines.size(); ++l) lines[l] = static_cast<int>(l);
    try {
      const auto r = e.residual(build(std::pow(*e.measured().speed_rpm / primary_rpm_, exponent)), lines);
      out.insert(out.end(), r.begin(), r.end());
    } catch (const InputError&) {
      throw;
    } catch (const std::runtime_error&) {
      out.insert(out.end(), e.measured().entries.size() * lines.size(), {1e30, 0.0});
    }
  }
  return out;
}

std::vector<SpeedCheck> OtherSpeeds::report(const PlantModel& nominal, const PlantVariant& after, double window_threshold) {
  std::vector<SpeedCheck> out;
  for (auto& e : evals_) {
    const FrfData& meas = e.measured();
    SpeedCheck s;
    s.speed_rpm = *meas.speed_rpm;
    const PlantVariant before{nominal, 0.0};
    const FrfData model_before = e.model_frf(before), model_after = e.model_frf(after);
    const FrfComparison cb = compare_frf(model_before, meas), ca = compare_frf(model_after, meas);
    const double lines = static_cast<double>(meas.freq_hz.size() * meas.entries.size());
    s.nrmse_before = cb.nrmse;
    s.nrmse_after = ca.nrmse;
    s.chi2_per_line_before = cb.chi2 / lines;
    s.chi2_per_line_after = ca.chi2 / lines;
    double s2 = 0.0, h2 = 0.0;
    for (size_t k = 0; k < meas.entries.size(); ++k)
      for (size_t l = 0; l < meas.freq_hz.size(); ++l) {
        s2 += e.sigma(k, l) * e.sigma(k, l);
        h2 += std::norm(meas.entries[k].h[l]);
      }
    s.noise_floor_nrmse = h2 > 0 ? std::sqrt(s2 / h2) : 0.0;
    const auto modes = modes_in_band(after.plant, s.speed_rpm, meas.freq_hz.back());
    s.unexplained = locate_mismatches(after.plant, model_after, e, modes, window_threshold);
    out.push_back(std::move(s));
  }
  return out;
}

void write_speed_law(Link& l, double k, double c, double exponent, double rpm0) {
  std::vector<double> rpms;
  for (int i = 0; i <= 8; ++i) rpms.push_back(rpm0 * (0.5 + 0.125 * i));
  for (const auto& row : l.table) rpms.push_back(row.rpm);
  std::sort(rpms.begin(), rpms.end());
  rpms.erase(std::unique(rpms.begin(), rpms.end(), [](double a, double b) { return std::abs(a - b) <= 1e-9 * std::max(1.0, b); }),
             rpms.end());
  std::array<bool, static_cast<size_t>(kLinkCoefCount)> stated{};
  for (const auto& row : l.table)
    for (size_t i = 0; i < static_cast<size_t>(kLinkCoefCount); ++i) stated[i] = stated[i] || row.values[i].has_value();
  const auto at = [](LinkCoef cf) { return static_cast<size_t>(cf); };
  for (LinkCoef cf : {LinkCoef::kxy, LinkCoef::kyx, LinkCoef::cxy, LinkCoef::cyx}) stated[at(cf)] = true;
  std::vector<LinkTableRow> table;
  for (double rpm : rpms) {
    const LinkCoefficients v = l.at_speed(rpm);
    const double extra = std::pow(rpm / rpm0, exponent) - 1.0;  // the law beyond what rpm0's values hold
    LinkTableRow row;
    row.rpm = rpm;
    for (size_t i = 0; i < static_cast<size_t>(kLinkCoefCount); ++i)
      if (stated[i]) row.values[i] = v[i];
    *row.values[at(LinkCoef::kxy)] += k * extra;
    *row.values[at(LinkCoef::kyx)] -= k * extra;
    *row.values[at(LinkCoef::cxy)] += c * extra;
    *row.values[at(LinkCoef::cyx)] -= c * extra;
    table.push_back(row);
  }
  l.table = std::move(table);
}

}  // namespace ambdiag::detail
