// Measured vs model FRF before and after the diagnosis, as SVG.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "ambdiag/algorithms/diagnosis/diagnosis.h"
#include "ambdiag/core/svg_plot.h"

namespace ambdiag {

std::string diagnosis_svg(const DiagnosisResult& r, const FrfData& measured, int max_entries) {
  // Entries to show: the symptoms' entries (largest change first), else the
  // measured file's first entries.
  std::vector<std::pair<std::string, std::string>> shown;
  for (const auto& s : r.symptoms)
    if (s.kind == "entry" && static_cast<int>(shown.size()) < max_entries) shown.push_back({s.output, s.input});
  for (const auto& e : measured.entries)
    if (static_cast<int>(shown.size()) < max_entries && std::find(shown.begin(), shown.end(), std::pair{e.output, e.input}) == shown.end())
      shown.push_back({e.output, e.input});

  SvgFigure fig;
  const std::string best = r.faults.empty() ? "no fault" : r.faults.front().name;
  char buf[200];
  std::snprintf(buf, sizeof buf, "Diagnosis: %s (NRMSE model vs measured: before %.3f, after %.3f)", best.c_str(), r.nrmse_before,
                r.nrmse_after);
  fig.title = buf;
  fig.x_label = "frequency (Hz)";
  for (const auto& [out, in] : shown) {
    const FrfEntry* m = measured.find(out, in);
    const FrfEntry* b = r.model_before.find(out, in);
    const FrfEntry* a = r.model_after.find(out, in);
    if (!m) continue;
    SvgPanel p;
    p.y_label = "|H " + out + "/" + in + "| (m/N)";
    p.log_y = true;
    auto series = [&](const FrfEntry* e, const std::string& label, const std::string& color, bool dashed) {
      SvgSeries s{label, measured.freq_hz, {}, color, false, dashed};
      for (const auto& h : e->h) s.y.push_back(std::abs(h));
      return s;
    };
    p.series.push_back(series(m, "measured", "#333333", false));
    if (b) p.series.push_back(series(b, "model, healthy", "#1f77b4", true));
    if (a) p.series.push_back(series(a, "model, " + best, "#d62728", false));
    fig.panels.push_back(p);
  }
  return render_svg(fig);
}

}  // namespace ambdiag
