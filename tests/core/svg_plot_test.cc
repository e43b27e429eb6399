#include "ambdiag/core/svg_plot.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include "xml_check.h"

namespace ambdiag {
namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

SvgSeries line(std::vector<double> x, std::vector<double> y, std::string label = "") {
  SvgSeries s;
  s.x = std::move(x);
  s.y = std::move(y);
  s.label = std::move(label);
  return s;
}

size_t count(const std::string& s, const std::string& what) {
  size_t n = 0;
  for (size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + what.size())) ++n;
  return n;
}

// A magnitude/phase FRF figure: log panel over a linear one, a band, a
// dashed reference, markers and a legend.
SvgFigure frf_figure() {
  SvgFigure f;
  f.title = "FRF xAx/fAx";
  f.x_label = "frequency (Hz)";
  SvgPanel mag{.y_label = "|H| (m/N)", .log_y = true, .series = {}, .bands = {{180.0, 200.0}}, .y_range = {}};
  SvgPanel phase{.y_label = "phase (deg)", .log_y = false, .series = {}, .bands = {}, .y_range = {}};
  SvgSeries meas = line({}, {}, "measured"), model = line({}, {}, "model"), ph;
  meas.markers = true;
  model.color = "#000000";
  model.dashed = true;
  for (int i = 1; i <= 100; ++i) {
    const double f_hz = 10.0 * i, r = f_hz / 190.0;
    const double mag_m_per_n = 1e-6 / std::hypot(1 - r * r, 0.2 * r);
    meas.x.push_back(f_hz);
    meas.y.push_back(mag_m_per_n * 1.01);
    model.x.push_back(f_hz);
    model.y.push_back(mag_m_per_n);
    ph.x.push_back(f_hz);
    ph.y.push_back(-std::atan2(0.2 * r, 1 - r * r) * 180.0 / std::numbers::pi);
  }
  mag.series = {meas, model};
  phase.series = {ph};
  f.panels = {mag, phase};
  return f;
}

TEST(SvgPlot, WritesWellFormedTwoPanelFigure) {
  const std::string svg = render_svg(frf_figure());
  int elements = 0;
  EXPECT_EQ(testing::xml_problem(svg, &elements), "");
  EXPECT_GT(elements, 100);  // 100 markers alone
  EXPECT_EQ(svg.rfind("<?xml", 0), 0u);
  EXPECT_NE(svg.find("<svg xmlns=\"http://www.w3.org/2000/svg\""), std::string::npos);
  EXPECT_EQ(count(svg, "<circle"), 100u + 1u);    // markers plus the legend's sample
  EXPECT_EQ(count(svg, "stroke-dasharray"), 2u);  // the model line and its legend sample
  EXPECT_EQ(count(svg, "fill=\"#fdb863\""), 1u);  // one band
  EXPECT_EQ(count(svg, "<clipPath"), 2u);
  EXPECT_NE(svg.find(">measured</text>"), std::string::npos);
  EXPECT_NE(svg.find(">frequency (Hz)</text>"), std::string::npos);
}

TEST(SvgPlot, LogAxisTicksAreWholeDecades) {
  const auto t = decade_ticks(3e-7, 2e-3);
  ASSERT_EQ(t.size(), 6u);
  for (size_t i = 0; i < t.size(); ++i) EXPECT_DOUBLE_EQ(t[i], std::pow(10.0, -7.0 + static_cast<double>(i)));
  // Exact decades stay the end ticks; a narrow range still gets two decades.
  EXPECT_EQ(decade_ticks(1e-3, 1.0).size(), 4u);
  EXPECT_EQ(decade_ticks(2.0, 3.0), (std::vector<double>{1.0, 10.0}));
  // Forty decades: every n-th, no more than asked for, still covering.
  const auto wide = decade_ticks(1e-20, 1e20, 8);
  EXPECT_LE(wide.size(), 8u);
  EXPECT_LE(wide.front(), 1e-20);
  EXPECT_GE(wide.back(), 1e20);

  const std::string svg = render_svg(frf_figure());
  // Magnitudes 3.7e-8 .. 5e-6 m/N: labels at the decades 1e-8 .. 1e-5 only.
  for (const char* label : {">1e-8<", ">1e-7<", ">1e-6<", ">1e-5<"}) {
    EXPECT_NE(svg.find(label), std::string::npos) << label;
  }
  EXPECT_EQ(svg.find(">1e-9<"), std::string::npos);
  EXPECT_EQ(svg.find(">1e-4<"), std::string::npos);
}

TEST(SvgPlot, NiceTicksUseOneTwoFiveSteps) {
  EXPECT_EQ(nice_ticks(0.0, 2950.0), (std::vector<double>{0, 500, 1000, 1500, 2000, 2500, 3000}));
  const auto t = nice_ticks(-0.31, 0.69);
  EXPECT_EQ(t.front(), -0.4);
  EXPECT_EQ(t.back(), 0.8);
  EXPECT_NE(std::find(t.begin(), t.end(), 0.0), t.end());  // an exact zero, not 1e-17
  EXPECT_EQ(nice_ticks(5.0, 5.0).size() >= 2, true);       // a constant still gets an axis
}

TEST(SvgPlot, EscapesTextAndAttributes) {
  SvgFigure f;
  f.title = "a < b & \"c\" > d";
  f.x_label = "speed <rpm>";
  f.panels.push_back(SvgPanel{.y_label = "f & g", .log_y = false, .series = {}, .bands = {}, .y_range = {}});
  f.panels[0].series.push_back(line({0, 1}, {0, 1}, "<1x>"));
  f.panels[0].series[0].color = "red\"/><script";
  const std::string svg = render_svg(f);
  EXPECT_EQ(testing::xml_problem(svg), "");
  EXPECT_NE(svg.find("a &lt; b &amp; &quot;c&quot; &gt; d"), std::string::npos);
  EXPECT_NE(svg.find("speed &lt;rpm&gt;"), std::string::npos);
  EXPECT_NE(svg.find("&lt;1x&gt;"), std::string::npos);
  EXPECT_EQ(svg.find("<script"), std::string::npos);
  EXPECT_EQ(xml_escape("x\x01y"), "xy");  // control characters are not XML
}

TEST(SvgPlot, SkipsNonFinitePointsAndBreaksTheLine) {
  SvgFigure f;
  SvgPanel lin{.y_label = "y", .log_y = false, .series = {}, .bands = {}, .y_range = {}};
  lin.series.push_back(line({0, 1, 2, 3, 4, 5, 6}, {1, 2, kNan, 3, 4, kInf, 5}));
  SvgPanel log{.y_label = "y", .log_y = true, .series = {}, .bands = {{kNan, 2.0}}, .y_range = {}};
  log.series.push_back(line({0, 1, 2, 3, 4}, {1, 0, -1, 10, 100}));
  f.panels = {lin, log};
  const std::string svg = render_svg(f);
  EXPECT_EQ(testing::xml_problem(svg), "");
  // Linear panel: runs {0,1} and {3,4} are lines, {6} a dot; log panel: {0} a dot, {3,4} a line.
  EXPECT_EQ(count(svg, "<polyline"), 3u);
  EXPECT_EQ(count(svg, "<circle"), 2u);
  EXPECT_EQ(svg.find("nan"), std::string::npos);
  EXPECT_EQ(svg.find("inf"), std::string::npos);
  EXPECT_EQ(count(svg, "fill=\"#fdb863\""), 0u);  // a band with a NaN edge is skipped
}

// A phase wrapped to +-180 deg: the line breaks at each wrap (two here)
// instead of crossing the panel, and nowhere else.
TEST(SvgPlot, BreaksTheLineWherePhaseWraps) {
  SvgSeries s = line({1, 2, 3, 4, 5, 6}, {170, 179, -179, -170, 175, 178});
  break_at_jumps(s, 180.0);
  ASSERT_EQ(s.x.size(), 8u);
  EXPECT_TRUE(std::isnan(s.y[2]));
  EXPECT_DOUBLE_EQ(s.x[2], 2.5);
  EXPECT_TRUE(std::isnan(s.y[5]));
  EXPECT_EQ(std::count_if(s.y.begin(), s.y.end(), [](double v) { return std::isnan(v); }), 2);
  SvgFigure f;
  f.panels.push_back({.y_label = "phase (deg)", .log_y = false, .series = {s}, .bands = {}, .y_range = {}});
  EXPECT_EQ(count(render_svg(f), "<polyline"), 3u);
  SvgSeries smooth = line({1, 2, 3}, {-10, -90, -170});
  break_at_jumps(smooth, 180.0);
  EXPECT_EQ(smooth.y.size(), 3u);
}

TEST(SvgPlot, DegenerateInputsStillGiveADocument) {
  EXPECT_EQ(testing::xml_problem(render_svg(SvgFigure{})), "");
  SvgFigure f;
  f.width = -5;
  f.height_per_panel = 0;
  SvgPanel p{.y_label = "", .log_y = true, .series = {}, .bands = {{1, 2}}, .y_range = {{-1.0, 0.0}}};
  p.series.push_back(SvgSeries{});  // empty
  p.series.push_back(line({kNan, kNan}, {1, 2}, "no points"));
  p.series.push_back(line({1, 2, 3}, {1}, "short"));  // x, y lengths differ
  p.series.push_back(line({-1e300, 1e300}, {1e-300, 1e300}, "huge"));
  f.panels = {p, SvgPanel{}};
  const std::string svg = render_svg(f);
  EXPECT_EQ(testing::xml_problem(svg), "");
  EXPECT_EQ(svg.find("nan"), std::string::npos);
  EXPECT_EQ(svg.find("inf"), std::string::npos);
}

TEST(SvgPlot, FixedRangesClipTheData) {
  SvgFigure f;
  f.x_range = {{0.0, 10.0}};
  SvgPanel p{.y_label = "", .log_y = false, .series = {}, .bands = {}, .y_range = {{0.0, 1.0}}};
  p.series.push_back(line({0, 5, 20}, {0, 0.5, 40}));
  f.panels = {p};
  const std::string svg = render_svg(f);
  EXPECT_EQ(testing::xml_problem(svg), "");
  EXPECT_NE(svg.find("clip-path=\"url(#ambdiag-clip-0)\""), std::string::npos);
  EXPECT_NE(svg.find(">10</text>"), std::string::npos);  // last x tick is the fixed end
  EXPECT_EQ(svg.find(">20</text>"), std::string::npos);
}

}  // namespace
}  // namespace ambdiag
