#include "ambdiag/core/svg_plot.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

namespace ambdiag {

namespace {

constexpr std::array<const char*, 10> kPalette = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd",
                                                  "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};
constexpr double kMarginLeft = 84, kMarginRight = 24, kPanelPad = 10, kBottom = 52;
// Pixel coordinates are clamped so that absurd data cannot produce absurd text.
constexpr double kMaxPx = 1e6;

std::string num(double v, const char* f = "%.2f") {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

std::string tick_label(double v, bool log) {
  if (v == 0.0) return "0";
  if (log) {
    const int k = static_cast<int>(std::lround(std::log10(v)));
    if (k < -3 || k > 4) return "1e" + std::to_string(k);
  }
  return num(v, "%.6g");
}

struct Axis {
  double lo = 0.0, hi = 1.0;
  bool log = false;
  std::vector<double> ticks;
  // Fraction 0..1 of the way from lo to hi (in log10 on a log axis).
  double frac(double v) const {
    if (log) return (std::log10(v) - std::log10(lo)) / (std::log10(hi) - std::log10(lo));
    return (v - lo) / (hi - lo);
  }
  bool valid(double v) const { return std::isfinite(v) && (!log || v > 0.0); }
};

// Axis from the data extent [lo, hi] (or a fixed range), widened to ticks.
Axis make_axis(double lo, double hi, bool log, const std::optional<std::pair<double, double>>& fixed) {
  Axis a;
  a.log = log;
  if (fixed && std::isfinite(fixed->first) && std::isfinite(fixed->second) && fixed->second > fixed->first &&
      (!log || fixed->first > 0.0)) {
    a.lo = fixed->first;
    a.hi = fixed->second;
    const auto t = log ? decade_ticks(a.lo, a.hi) : nice_ticks(a.lo, a.hi);
    const double eps = 1e-9 * (a.hi - a.lo);
    for (double v : t)
      if (v >= a.lo - eps && v <= a.hi + eps) a.ticks.push_back(v);
    return a;
  }
  if (!(lo <= hi)) {  // no data
    lo = log ? 1.0 : 0.0;
    hi = log ? 10.0 : 1.0;
  }
  a.ticks = log ? decade_ticks(lo, hi) : nice_ticks(lo, hi);
  a.lo = a.ticks.front();
  a.hi = a.ticks.back();
  return a;
}

class Writer {
 public:
  explicit Writer(const SvgFigure& f) : fig_(f) {}
  std::string render();

 private:
  void panel(size_t index, const Axis& x, double top, double bottom);
  void series(const SvgSeries& s, const std::string& color, const Axis& x, const Axis& y);
  void legend(const SvgPanel& p, const std::vector<std::string>& colors);
  double px(const Axis& a, double v, double p0, double p1) const {
    const double f = a.frac(v);
    return std::isfinite(f) ? std::clamp(p0 + f * (p1 - p0), -kMaxPx, kMaxPx) : p0;
  }
  void text(double x, double y, const std::string& s, const char* anchor, const std::string& extra = "") {
    out_ += "<text x=\"" + num(x) + "\" y=\"" + num(y) + "\" text-anchor=\"" + anchor + "\"" + extra + ">" +
            xml_escape(s) + "</text>\n";
  }

  const SvgFigure& fig_;
  std::string out_;
  double left_ = 0, right_ = 0, top_ = 0, bottom_ = 0;  // current plot area
};

std::string Writer::render() {
  const double width = std::max(fig_.width, 200);
  const double panel_h = std::max(fig_.height_per_panel, 80);
  const double title_h = fig_.title.empty() ? 12.0 : 36.0;
  const double height = title_h + panel_h * static_cast<double>(fig_.panels.size()) + kBottom;
  left_ = kMarginLeft;
  right_ = width - kMarginRight;

  double xlo = HUGE_VAL, xhi = -HUGE_VAL;
  for (const auto& p : fig_.panels)
    for (const auto& s : p.series)
      for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
        if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i]) || (p.log_y && s.y[i] <= 0.0)) continue;
        xlo = std::min(xlo, s.x[i]);
        xhi = std::max(xhi, s.x[i]);
      }
  const Axis x = make_axis(xlo, xhi, false, fig_.x_range);

  out_ = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  out_ += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + num(width, "%.0f") + "\" height=\"" +
          num(height, "%.0f") + "\" viewBox=\"0 0 " + num(width, "%.0f") + " " + num(height, "%.0f") +
          "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  out_ += "<rect x=\"0\" y=\"0\" width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  if (!fig_.title.empty())
    text(width / 2, 24, fig_.title, "middle", " font-size=\"15\" font-weight=\"bold\"");
  for (size_t i = 0; i < fig_.panels.size(); ++i) {
    const double top = title_h + panel_h * static_cast<double>(i) + kPanelPad;
    panel(i, x, top, top + panel_h - 2 * kPanelPad);
  }
  // Shared x axis labels under the last panel.
  const double base = fig_.panels.empty() ? title_h : bottom_;
  for (double t : x.ticks) text(px(x, t, left_, right_), base + 16, tick_label(t, false), "middle");
  if (!fig_.x_label.empty()) text((left_ + right_) / 2, base + 38, fig_.x_label, "middle");
  out_ += "</svg>\n";
  return std::move(out_);
}

void Writer::panel(size_t index, const Axis& x, double top, double bottom) {
  const SvgPanel& p = fig_.panels[index];
  top_ = top;
  bottom_ = bottom;
  double lo = HUGE_VAL, hi = -HUGE_VAL;
  for (const auto& s : p.series)
    for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i]) || (p.log_y && s.y[i] <= 0.0)) continue;
      if (s.x[i] < x.lo || s.x[i] > x.hi) continue;
      lo = std::min(lo, s.y[i]);
      hi = std::max(hi, s.y[i]);
    }
  const Axis y = make_axis(lo, hi, p.log_y, p.y_range);
  const std::string clip = "ambdiag-clip-" + std::to_string(index);
  out_ += "<defs><clipPath id=\"" + clip + "\"><rect x=\"" + num(left_) + "\" y=\"" + num(top_) +
          "\" width=\"" + num(right_ - left_) + "\" height=\"" + num(bottom_ - top_) +
          "\"/></clipPath></defs>\n";
  out_ += "<g clip-path=\"url(#" + clip + ")\">\n";
  for (const auto& [b0, b1] : p.bands) {
    if (!std::isfinite(b0) || !std::isfinite(b1)) continue;
    const double a = px(x, std::min(b0, b1), left_, right_), b = px(x, std::max(b0, b1), left_, right_);
    out_ += "<rect x=\"" + num(a) + "\" y=\"" + num(top_) + "\" width=\"" + num(b - a) + "\" height=\"" +
            num(bottom_ - top_) + "\" fill=\"#fdb863\" fill-opacity=\"0.35\"/>\n";
  }
  out_ += "<g stroke=\"#dddddd\" stroke-width=\"1\">\n";
  for (double t : x.ticks) {
    const double xp = px(x, t, left_, right_);
    out_ += "<line x1=\"" + num(xp) + "\" y1=\"" + num(top_) + "\" x2=\"" + num(xp) + "\" y2=\"" +
            num(bottom_) + "\"/>\n";
  }
  for (double t : y.ticks) {
    const double yp = px(y, t, bottom_, top_);
    out_ += "<line x1=\"" + num(left_) + "\" y1=\"" + num(yp) + "\" x2=\"" + num(right_) + "\" y2=\"" +
            num(yp) + "\"/>\n";
  }
  out_ += "</g>\n";
  std::vector<std::string> colors;
  size_t next = 0;
  for (const auto& s : p.series) {
    colors.push_back(s.color.empty() ? kPalette[next++ % kPalette.size()] : s.color);
    series(s, colors.back(), x, y);
  }
  out_ += "</g>\n";
  out_ += "<rect x=\"" + num(left_) + "\" y=\"" + num(top_) + "\" width=\"" + num(right_ - left_) +
          "\" height=\"" + num(bottom_ - top_) + "\" fill=\"none\" stroke=\"black\"/>\n";
  for (double t : y.ticks) text(left_ - 6, px(y, t, bottom_, top_) + 4, tick_label(t, y.log), "end");
  if (!p.y_label.empty()) {
    const double mid = (top_ + bottom_) / 2;
    text(18, mid, p.y_label, "middle", " transform=\"rotate(-90 18 " + num(mid) + ")\"");
  }
  legend(p, colors);
}

void Writer::series(const SvgSeries& s, const std::string& color, const Axis& x, const Axis& y) {
  const std::string c = xml_escape(color);
  const size_t n = std::min(s.x.size(), s.y.size());
  const double w = std::isfinite(s.line_width_px) && s.line_width_px > 0 ? s.line_width_px : 1.5;
  auto point = [&](size_t i) {
    return num(px(x, s.x[i], left_, right_)) + "," + num(px(y, s.y[i], bottom_, top_));
  };
  auto dot = [&](size_t i, double r) {
    out_ += "<circle cx=\"" + num(px(x, s.x[i], left_, right_)) + "\" cy=\"" +
            num(px(y, s.y[i], bottom_, top_)) + "\" r=\"" + num(r) + "\" fill=\"" + c + "\"/>\n";
  };
  if (s.markers) {
    for (size_t i = 0; i < n; ++i)
      if (x.valid(s.x[i]) && y.valid(s.y[i])) dot(i, 3.5);
    return;
  }
  // One polyline per run of valid points; an invalid point breaks the line.
  size_t i = 0;
  while (i < n) {
    while (i < n && !(x.valid(s.x[i]) && y.valid(s.y[i]))) ++i;
    size_t j = i;
    while (j < n && x.valid(s.x[j]) && y.valid(s.y[j])) ++j;
    if (j - i == 1) dot(i, w);
    if (j - i >= 2) {
      out_ += "<polyline fill=\"none\" stroke=\"" + c + "\" stroke-width=\"" + num(w) + "\"" +
              (s.dashed ? " stroke-dasharray=\"6 4\"" : "") + " points=\"";
      for (size_t k = i; k < j; ++k) out_ += (k > i ? " " : "") + point(k);
      out_ += "\"/>\n";
    }
    i = j;
  }
}

void Writer::legend(const SvgPanel& p, const std::vector<std::string>& colors) {
  size_t rows = 0, chars = 0;
  for (const auto& s : p.series)
    if (!s.label.empty()) {
      ++rows;
      chars = std::max(chars, s.label.size());
    }
  if (rows == 0) return;
  const double w = 40 + 7.0 * static_cast<double>(chars), h = 8 + 16.0 * static_cast<double>(rows);
  const double x0 = right_ - w - 6, y0 = top_ + 6;
  out_ += "<rect x=\"" + num(x0) + "\" y=\"" + num(y0) + "\" width=\"" + num(w) + "\" height=\"" + num(h) +
          "\" fill=\"white\" fill-opacity=\"0.85\" stroke=\"#999999\"/>\n";
  double row_y = y0 + 16;
  for (size_t i = 0; i < p.series.size(); ++i) {
    const auto& s = p.series[i];
    if (s.label.empty()) continue;
    const std::string c = xml_escape(colors[i]);
    if (s.markers) {
      out_ += "<circle cx=\"" + num(x0 + 18) + "\" cy=\"" + num(row_y - 4) + "\" r=\"3.5\" fill=\"" + c +
              "\"/>\n";
    } else {
      out_ += "<line x1=\"" + num(x0 + 6) + "\" y1=\"" + num(row_y - 4) + "\" x2=\"" + num(x0 + 30) +
              "\" y2=\"" + num(row_y - 4) + "\" stroke=\"" + c + "\" stroke-width=\"2\"" +
              (s.dashed ? " stroke-dasharray=\"6 4\"" : "") + "/>\n";
    }
    text(x0 + 36, row_y, s.label, "start");
    row_y += 16;
  }
}

}  // namespace

void break_at_jumps(SvgSeries& s, double max_jump) {
  const size_t n = std::min(s.x.size(), s.y.size());
  std::vector<double> x, y;
  x.reserve(n + n / 8);
  y.reserve(n + n / 8);
  for (size_t i = 0; i < n; ++i) {
    if (i > 0 && std::abs(s.y[i] - s.y[i - 1]) > max_jump) {
      x.push_back((s.x[i - 1] + s.x[i]) / 2);
      y.push_back(std::numeric_limits<double>::quiet_NaN());
    }
    x.push_back(s.x[i]);
    y.push_back(s.y[i]);
  }
  s.x = std::move(x);
  s.y = std::move(y);
}

std::vector<double> nice_ticks(double lo, double hi, int target) {
  if (!std::isfinite(lo) || !std::isfinite(hi)) return {0.0, 1.0};
  if (lo > hi) std::swap(lo, hi);
  if (hi - lo <= 1e-12 * std::max(std::abs(lo), std::abs(hi))) {  // one value: open a window around it
    const double d = lo == 0.0 ? 1.0 : 0.1 * std::abs(lo);
    lo -= d;
    hi += d;
  }
  const double raw = (hi - lo) / std::max(target, 1);
  if (!std::isfinite(raw) || raw <= 0.0) return {lo, hi};
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double r = raw / mag;
  const double step = (r < 1.5 ? 1.0 : r < 3.5 ? 2.0 : r < 7.5 ? 5.0 : 10.0) * mag;
  const double first = std::floor(lo / step), last = std::ceil(hi / step);
  if (!(last - first < 1000.0)) return {lo, hi};
  std::vector<double> t;
  for (double k = first; k <= last; k += 1.0) {
    const double v = k * step;
    t.push_back(std::abs(v) < 1e-9 * step ? 0.0 : v);  // no "-0" or 1e-17 labels
  }
  return t;
}

std::vector<double> decade_ticks(double lo, double hi, int max_ticks) {
  if (!(lo > 0.0) || !(hi > 0.0) || !std::isfinite(lo) || !std::isfinite(hi)) return {1.0, 10.0};
  if (lo > hi) std::swap(lo, hi);
  // Tolerate rounding in log10 of an exact power of ten.
  const int klo = std::max(-300, static_cast<int>(std::floor(std::log10(lo) + 1e-9)));
  int khi = std::min(300, static_cast<int>(std::ceil(std::log10(hi) - 1e-9)));
  if (khi <= klo) khi = klo + 1;
  const int step = std::max(1, (khi - klo + std::max(max_ticks, 2) - 2) / (std::max(max_ticks, 2) - 1));
  std::vector<double> t;
  for (int k = klo;; k += step) {
    t.push_back(std::pow(10.0, k));
    if (k >= khi) break;
  }
  return t;
}

std::string xml_escape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char ch : text) {
    switch (ch) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        // Control characters other than tab and newlines are not allowed in XML 1.0.
        if (static_cast<unsigned char>(ch) >= 0x20 || ch == '\t' || ch == '\n' || ch == '\r') out += ch;
    }
  }
  return out;
}

std::string render_svg(const SvgFigure& figure) { return Writer(figure).render(); }

}  // namespace ambdiag
