// The explain report's figure (explain.h, explain_svg).
#include <algorithm>
#include <cmath>

#include "ambdiag/algorithms/explain/explain.h"
#include "ambdiag/core/svg_plot.h"

namespace ambdiag {

// Measured vs old model vs improved model for the entries with the largest
// mismatch (up to four), magnitude and phase, mismatch bands shaded.
std::string explain_svg(const ExplainResult& r, const FrfData& meas) {
  std::vector<size_t> order(r.entries.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::sort(order.begin(), order.end(),
            [&](size_t a, size_t b) { return r.entries[a].chi2_per_line_before > r.entries[b].chi2_per_line_before; });
  std::vector<std::pair<double, double>> bands;
  for (const auto& m : r.mismatches) bands.push_back({m.band_lo_hz, m.band_hi_hz});
  SvgFigure fig;
  fig.title = "explain: measured vs model vs improved model (bands: mismatch beyond noise)";
  fig.x_label = "frequency (Hz)";
  for (size_t k = 0; k < std::min<size_t>(4, order.size()); ++k) {
    const FrfEntry& me = meas.entries[order[k]];
    const FrfEntry* mb = r.model_before.find(me.output, me.input);
    const FrfEntry* ma = r.model_after.find(me.output, me.input);
    SvgPanel mag, ph;
    mag.y_label = "|H " + me.output + "/" + me.input + "| (m/N)";
    mag.log_y = true;
    mag.bands = bands;
    ph.y_label = "phase " + me.output + "/" + me.input + " (deg)";
    ph.bands = bands;
    ph.y_range = {{-180.0, 180.0}};
    auto add = [&](const std::string& label, const std::vector<std::complex<double>>& h, const std::string& color, bool dashed) {
      SvgSeries sm{label, meas.freq_hz, {}, color, false, dashed};
      SvgSeries sp{"", meas.freq_hz, {}, color, false, dashed};
      for (const auto& v : h) {
        sm.y.push_back(std::abs(v));
        sp.y.push_back(std::arg(v) * 180.0 / M_PI);
      }
      break_at_jumps(sp, 180.0);  // wrapped to +-180 deg: a gap at each wrap, not a stroke across
      mag.series.push_back(sm);
      ph.series.push_back(sp);
    };
    add("measured", me.h, "#333333", false);
    add("model", mb->h, "#d62728", true);
    add("improved model", ma->h, "#1f77b4", false);
    fig.panels.push_back(mag);
    fig.panels.push_back(ph);
  }
  return render_svg(fig);
}

}  // namespace ambdiag
