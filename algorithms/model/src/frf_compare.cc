#include "ambdiag/algorithms/model/frf_compare.h"

#include <cmath>
#include <limits>

#include "ambdiag/core/error.h"

namespace ambdiag {

FrfData model_frf_like(const PlantModel& plant, const FrfData& measured, const FrfSynthesisOptions& options) {
  const double rpm = measured.speed_rpm.value_or(plant.speed_rpm);
  const FrfData full = synthesize_frf(plant, rpm, measured.freq_hz, options);
  FrfData out;
  out.speed_rpm = rpm;
  out.freq_hz = measured.freq_hz;
  for (const auto& e : measured.entries) {
    const FrfEntry* m = full.find(e.output, e.input);
    if (!m) throw InputError("measured entry " + e.output + "/" + e.input + ": the plant model has no such sensor/actuator pair");
    out.entries.push_back({e.output, e.input, m->h, {}, {}});
  }
  return out;
}

FrfComparison compare_frf(const FrfData& model, const FrfData& measured) {
  if (model.freq_hz != measured.freq_hz) throw InputError("compare_frf: model and measurement are on different frequency grids");
  FrfComparison c;
  double diff2 = 0.0, meas2 = 0.0;
  for (const auto& me : measured.entries) {
    const FrfEntry* mo = model.find(me.output, me.input);
    if (!mo) continue;
    FrfEntryComparison ec{me.output, me.input, static_cast<int>(me.h.size()), 0.0, 0.0};
    double d2 = 0.0, m2 = 0.0;
    const bool has_sigma = me.sigma.size() == me.h.size();
    for (std::size_t k = 0; k < me.h.size(); ++k) {
      const double d = std::norm(mo->h[k] - me.h[k]);
      d2 += d;
      m2 += std::norm(me.h[k]);
      if (has_sigma && me.sigma[k] > 0.0) ec.chi2 += d / (me.sigma[k] * me.sigma[k]);
    }
    ec.nrmse = m2 > 0.0 ? std::sqrt(d2 / m2) : std::numeric_limits<double>::infinity();
    if (has_sigma) {
      c.chi2 += ec.chi2;
      c.chi2_lines += ec.lines;
    } else {
      ec.chi2 = std::numeric_limits<double>::quiet_NaN();
    }
    diff2 += d2;
    meas2 += m2;
    c.entries.push_back(ec);
  }
  if (c.entries.empty()) throw InputError("compare_frf: model and measurement share no FRF entry");
  c.nrmse = meas2 > 0.0 ? std::sqrt(diff2 / meas2) : std::numeric_limits<double>::infinity();
  return c;
}

}  // namespace ambdiag
