// A small line/scatter plot writer with no dependencies: one figure of
// panels stacked vertically that share the x axis (e.g. FRF magnitude over
// phase, or a Campbell diagram over its log decrement), rendered as one
// self-contained SVG document.
//
// Points with a non-finite coordinate (or y <= 0 on a log axis) are skipped
// and break the polyline; empty series and empty panels are fine. Axis
// ranges default to the data, widened to nice tick values (1, 2, 5 x 10^k;
// whole decades on a log axis). Text is XML-escaped.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace ambdiag {

struct SvgSeries {
  std::string label;  // legend entry; empty: not in the legend
  std::vector<double> x, y;
  std::string color;     // any SVG colour; empty: next colour of the palette
  bool markers = false;  // circles at the points instead of a line
  bool dashed = false;
  double line_width_px = 1.5;
};

struct SvgPanel {
  std::string y_label;  // with its unit, e.g. "|H| (m/N)"
  bool log_y = false;
  std::vector<SvgSeries> series;
  std::vector<std::pair<double, double>> bands;      // shaded x ranges (x0, x1)
  std::optional<std::pair<double, double>> y_range;  // fixed (lo, hi); default: from the data
};

struct SvgFigure {
  std::string title, x_label;
  std::vector<SvgPanel> panels;                      // top to bottom, sharing the x axis
  std::optional<std::pair<double, double>> x_range;  // fixed (lo, hi); default: from the data
  int width = 900;
  int height_per_panel = 320;
};

// The figure as an SVG document (UTF-8 text).
std::string render_svg(const SvgFigure& figure);

// Breaks the series' line (a NaN point between the two) wherever
// consecutive y values differ by more than `max_jump`: a phase wrapped to
// +-180 deg jumps by about 360 at each wrap, which a line would draw as a
// stroke across the whole panel.
void break_at_jumps(SvgSeries& series, double max_jump);

// Tick values covering [lo, hi] with steps of 1, 2 or 5 x 10^k, about
// `target` of them; the first tick is <= lo and the last >= hi.
std::vector<double> nice_ticks(double lo, double hi, int target = 6);
// Decade ticks 10^k covering [lo, hi] (lo > 0), at least two; every n-th
// decade when the range spans many.
std::vector<double> decade_ticks(double lo, double hi, int max_ticks = 8);
// Escapes &, <, >, " and ' for XML text and attributes.
std::string xml_escape(std::string_view text);

}  // namespace ambdiag
