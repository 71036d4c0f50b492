#include "support/report/svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "support/report/text_output.h"

namespace cslam::report {

namespace {

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

// A length in tenths of a pixel as the shortest decimal text: 123 -> "12.3", -5 -> "-.5", 40 -> "4".
std::string tenths(long v) {
  const bool neg = v < 0;
  const long a = neg ? -v : v;
  std::string out = neg ? "-" : "";
  if (a >= 10) out += std::to_string(a / 10);
  if (a % 10) out += "." + std::to_string(a % 10);
  if (a == 0) out = "0";
  return out;
}

// Tick label: enough decimals for the tick step, no trailing noise.
std::string tick_label(double v, double step) {
  if (std::abs(v) < step * 1e-9) v = 0;
  const int decimals = std::clamp(int(std::ceil(-std::log10(step) - 1e-9)), 0, 8);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

struct Range {
  double lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity();
  void add(double v) {
    if (!std::isfinite(v)) return;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  bool valid() const { return lo <= hi; }
  void widen() {  // a flat range gets some height
    if (hi - lo < 1e-12) {
      const double pad = std::abs(lo) > 1e-9 ? std::abs(lo) * 0.1 : 1.0;
      lo -= pad;
      hi += pad;
    }
  }
};

// Pixel rectangle of a panel's plot area and the data-to-pixel mapping.
struct Frame {
  double left, top, width, height;
  Range x, y;
  double px(double v) const { return left + (v - x.lo) / (x.hi - x.lo) * width; }
  double py(double v) const { return top + height - (v - y.lo) / (y.hi - y.lo) * height; }
};

void data_ranges(const Panel& p, Range& xr, Range& yr) {
  for (const auto& s : p.series)
    for (std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      xr.add(s.x[i]);
      yr.add(s.y[i]);
      if (i < s.y_low.size()) yr.add(s.y_low[i]);
      if (i < s.y_high.size()) yr.add(s.y_high[i]);
    }
  for (const auto& m : p.markers) {
    xr.add(m.x);
    yr.add(m.y);
  }
  for (const auto& v : p.vlines) xr.add(v.x);
  if (p.y_from_zero && yr.valid()) yr.add(0.0);
}

void draw_series(std::string& out, const Series& s, const Frame& f, std::size_t max_points) {
  const std::size_t n = std::min(s.x.size(), s.y.size());
  const std::vector<std::size_t> keep =
      decimate_min_max(std::vector<double>(s.y.begin(), s.y.begin() + long(n)), max_points);
  const std::string color = xml_escape(s.color);
  if (s.line) {
    // Compact path data: absolute "M" at each start, then relative "l" steps between positions
    // rounded to 0.1 px (so rounding errors do not accumulate).
    std::string d;
    bool pen_down = false;
    long px = 0, py = 0;  // previous position in 0.1 px
    for (std::size_t i : keep) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) {
        pen_down = false;
        continue;
      }
      const long x = std::lround(f.px(s.x[i]) * 10), y = std::lround(f.py(s.y[i]) * 10);
      if (!pen_down) {
        d += "M" + tenths(x) + " " + tenths(y);
      } else if (x != px || y != py) {
        const std::string dy = tenths(y - py);
        d += "l" + tenths(x - px) + (dy[0] == '-' ? "" : " ") + dy;
      }
      px = x;
      py = y;
      pen_down = true;
    }
    if (!d.empty())
      out += "<path d=\"" + d + "\" fill=\"none\" stroke=\"" + color + "\" stroke-width=\"" + fmt("%g", s.width) +
             "\"" + (s.dashed ? " stroke-dasharray=\"5,3\"" : "") + " stroke-linejoin=\"round\"/>\n";
  }
  for (std::size_t i : keep) {
    if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
    const double x = f.px(s.x[i]);
    if (i < s.y_low.size() && i < s.y_high.size() && std::isfinite(s.y_low[i]) && std::isfinite(s.y_high[i])) {
      const double y0 = f.py(s.y_low[i]), y1 = f.py(s.y_high[i]);
      out += "<path d=\"M" + fmt("%.1f", x) + " " + fmt("%.1f", y0) + "V" + fmt("%.1f", y1) + "M" + fmt("%.1f", x - 4) +
             " " + fmt("%.1f", y0) + "h8M" + fmt("%.1f", x - 4) + " " + fmt("%.1f", y1) + "h8\" stroke=\"" + color +
             "\" stroke-width=\"1.2\" fill=\"none\"/>\n";
    }
    if (s.marker_radius > 0)
      out += "<circle cx=\"" + fmt("%.1f", x) + "\" cy=\"" + fmt("%.1f", f.py(s.y[i])) + "\" r=\"" +
             fmt("%g", s.marker_radius) + "\" fill=\"" + color + "\"/>\n";
  }
}

void draw_axes(std::string& out, const Panel& p, const Frame& f) {
  out += "<rect x=\"" + fmt("%.1f", f.left) + "\" y=\"" + fmt("%.1f", f.top) + "\" width=\"" + fmt("%.1f", f.width) +
         "\" height=\"" + fmt("%.1f", f.height) + "\" fill=\"#ffffff\" stroke=\"#444444\" stroke-width=\"1\"/>\n";
  const auto xt = nice_ticks(f.x.lo, f.x.hi, std::max(3, int(f.width / 90)));
  const auto yt = nice_ticks(f.y.lo, f.y.hi, std::max(4, int(f.height / 40)));
  const double xstep = xt.size() > 1 ? xt[1] - xt[0] : 1.0, ystep = yt.size() > 1 ? yt[1] - yt[0] : 1.0;
  for (double t : xt) {
    const double x = f.px(t);
    out += "<path d=\"M" + fmt("%.1f", x) + " " + fmt("%.1f", f.top) + "V" + fmt("%.1f", f.top + f.height) +
           "\" stroke=\"#e4e4e4\" stroke-width=\"1\"/>\n";
    out += "<text x=\"" + fmt("%.1f", x) + "\" y=\"" + fmt("%.1f", f.top + f.height + 15) +
           "\" text-anchor=\"middle\">" + tick_label(t, xstep) + "</text>\n";
  }
  for (double t : yt) {
    const double y = f.py(t);
    out += "<path d=\"M" + fmt("%.1f", f.left) + " " + fmt("%.1f", y) + "H" + fmt("%.1f", f.left + f.width) +
           "\" stroke=\"#e4e4e4\" stroke-width=\"1\"/>\n";
    out += "<text x=\"" + fmt("%.1f", f.left - 6) + "\" y=\"" + fmt("%.1f", y + 4) + "\" text-anchor=\"end\">" +
           tick_label(t, ystep) + "</text>\n";
  }
  out += "<text x=\"" + fmt("%.1f", f.left + f.width / 2) + "\" y=\"" + fmt("%.1f", f.top + f.height + 32) +
         "\" text-anchor=\"middle\">" + xml_escape(p.x_label) + "</text>\n";
  const double ly = f.top + f.height / 2, lx = f.left - 52;
  out += "<text x=\"" + fmt("%.1f", lx) + "\" y=\"" + fmt("%.1f", ly) +
         "\" text-anchor=\"middle\" transform=\"rotate(-90 " + fmt("%.1f", lx) + " " + fmt("%.1f", ly) + ")\">" +
         xml_escape(p.y_label) + "</text>\n";
  out += "<text x=\"" + fmt("%.1f", f.left) + "\" y=\"" + fmt("%.1f", f.top - 7) + "\" font-weight=\"bold\">" +
         xml_escape(p.title) + "</text>\n";
}

void draw_legend(std::string& out, const Panel& p, double x, double y) {
  for (const auto& s : p.series) {
    if (s.label.empty()) continue;
    const std::string color = xml_escape(s.color);
    if (s.line)
      out += "<path d=\"M" + fmt("%.1f", x) + " " + fmt("%.1f", y) + "h22\" stroke=\"" + color + "\" stroke-width=\"" +
             fmt("%g", std::max(2.0, s.width)) + "\"" + (s.dashed ? " stroke-dasharray=\"5,3\"" : "") + "/>\n";
    else
      out +=
          "<circle cx=\"" + fmt("%.1f", x + 11) + "\" cy=\"" + fmt("%.1f", y) + "\" r=\"3\" fill=\"" + color + "\"/>\n";
    out +=
        "<text x=\"" + fmt("%.1f", x + 28) + "\" y=\"" + fmt("%.1f", y + 4) + "\">" + xml_escape(s.label) + "</text>\n";
    y += 16;
  }
  bool any_marker = false;
  for (const auto& m : p.markers) any_marker = any_marker || !m.label.empty();
  if (any_marker || !p.markers.empty()) {
    out += "<path d=\"M" + fmt("%.1f", x + 11) + " " + fmt("%.1f", y - 5) + "l5 5l-5 5l-5 -5z\" fill=\"#000000\"/>\n";
    out += "<text x=\"" + fmt("%.1f", x + 28) + "\" y=\"" + fmt("%.1f", y + 4) + "\">map fusion</text>\n";
  }
}

void draw_panel(std::string& out, const Panel& p, double left, double top, double width, double height,
                std::size_t max_points) {
  constexpr double kMarginLeft = 70, kMarginRight = 150, kMarginTop = 26, kMarginBottom = 42;
  Frame f{left + kMarginLeft,
          top + kMarginTop,
          width - kMarginLeft - kMarginRight,
          height - kMarginTop - kMarginBottom,
          {},
          {}};
  data_ranges(p, f.x, f.y);
  if (!f.x.valid() || !f.y.valid()) {
    f.x = Range{0, 1};
    f.y = Range{0, 1};
    draw_axes(out, p, f);
    out += "<text x=\"" + fmt("%.1f", f.left + f.width / 2) + "\" y=\"" + fmt("%.1f", f.top + f.height / 2) +
           "\" text-anchor=\"middle\" fill=\"#888888\">no data</text>\n";
    return;
  }
  if (std::isfinite(p.x_min)) f.x.lo = p.x_min;
  if (std::isfinite(p.x_max)) f.x.hi = p.x_max;
  f.x.widen();
  f.y.widen();
  const double ypad = (f.y.hi - f.y.lo) * 0.04;
  if (!(p.y_from_zero && f.y.lo == 0.0)) f.y.lo -= ypad;
  f.y.hi += ypad;
  if (p.equal_aspect) {  // metres per pixel equal on both axes, data centred, a margin around it
    const double xpad = (f.x.hi - f.x.lo) * 0.04;
    f.x.lo -= xpad;
    f.x.hi += xpad;
    const double s = std::max((f.x.hi - f.x.lo) / f.width, (f.y.hi - f.y.lo) / f.height);
    const double cx = (f.x.lo + f.x.hi) / 2, cy = (f.y.lo + f.y.hi) / 2;
    f.x = Range{cx - s * f.width / 2, cx + s * f.width / 2};
    f.y = Range{cy - s * f.height / 2, cy + s * f.height / 2};
  }
  draw_axes(out, p, f);
  out += "<g clip-path=\"url(#c" + fmt("%.0f", left) + "_" + fmt("%.0f", top) + ")\">\n";
  for (const auto& v : p.vlines) {
    const double x = f.px(v.x);
    out += "<path d=\"M" + fmt("%.1f", x) + " " + fmt("%.1f", f.top) + "V" + fmt("%.1f", f.top + f.height) +
           "\" stroke=\"" + xml_escape(v.color) + "\" stroke-width=\"1.2\" stroke-dasharray=\"3,3\"/>\n";
    if (!v.label.empty())
      out += "<text x=\"" + fmt("%.1f", x + 3) + "\" y=\"" + fmt("%.1f", f.top + 12) + "\" fill=\"" +
             xml_escape(v.color) + "\">" + xml_escape(v.label) + "</text>\n";
  }
  for (const auto& s : p.series) draw_series(out, s, f, max_points);
  for (const auto& m : p.markers) {
    if (!std::isfinite(m.x) || !std::isfinite(m.y)) continue;
    const double x = f.px(m.x), y = f.py(m.y);
    out += "<path d=\"M" + fmt("%.1f", x) + " " + fmt("%.1f", y - 6) + "l6 6l-6 6l-6 -6z\" fill=\"" +
           xml_escape(m.color) + "\" stroke=\"#000000\" stroke-width=\"1\"/>\n";
    if (!m.label.empty())
      out += "<text x=\"" + fmt("%.1f", x + 7) + "\" y=\"" + fmt("%.1f", y - 6) + "\">" + xml_escape(m.label) +
             "</text>\n";
  }
  out += "</g>\n";
  // The clip path is declared after use; SVG resolves references document-wide.
  out += "<clipPath id=\"c" + fmt("%.0f", left) + "_" + fmt("%.0f", top) + "\"><rect x=\"" + fmt("%.1f", f.left) +
         "\" y=\"" + fmt("%.1f", f.top) + "\" width=\"" + fmt("%.1f", f.width) + "\" height=\"" +
         fmt("%.1f", f.height) + "\"/></clipPath>\n";
  draw_legend(out, p, f.left + f.width + 12, f.top + 10);
}

}  // namespace

std::vector<double> nice_ticks(double lo, double hi, int target) {
  if (!std::isfinite(lo) || !std::isfinite(hi) || hi <= lo || target < 1) return {};
  const double raw = (hi - lo) / target;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  double step = mag;
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (m * mag >= raw) {
      step = m * mag;
      break;
    }
  std::vector<double> ticks;
  for (double t = std::ceil(lo / step - 1e-9) * step; t <= hi + step * 1e-9; t += step) {
    ticks.push_back(std::abs(t) < step * 1e-9 ? 0.0 : t);
    if (ticks.size() > 1000) break;
  }
  return ticks;
}

std::vector<std::size_t> decimate_min_max(const std::vector<double>& y, std::size_t max_points) {
  std::vector<std::size_t> keep;
  if (y.size() <= max_points || max_points < 4) {
    for (std::size_t i = 0; i < y.size(); ++i) keep.push_back(i);
    return keep;
  }
  const std::size_t buckets = (max_points - 2) / 2;
  keep.push_back(0);
  const std::size_t inner = y.size() - 2;
  for (std::size_t b = 0; b < buckets; ++b) {
    const std::size_t begin = 1 + b * inner / buckets, end = 1 + (b + 1) * inner / buckets;
    if (begin >= end) continue;
    std::size_t lo = begin, hi = begin;
    bool gap = false;
    for (std::size_t i = begin; i < end; ++i) {
      if (!std::isfinite(y[i])) {
        gap = true;
        continue;
      }
      if (!std::isfinite(y[lo]) || y[i] < y[lo]) lo = i;
      if (!std::isfinite(y[hi]) || y[i] > y[hi]) hi = i;
    }
    std::vector<std::size_t> chosen{std::min(lo, hi), std::max(lo, hi)};
    if (gap) {  // keep one NaN so that the line still breaks at the gap
      for (std::size_t i = begin; i < end; ++i)
        if (!std::isfinite(y[i])) {
          chosen.push_back(i);
          break;
        }
      std::sort(chosen.begin(), chosen.end());
    }
    for (std::size_t i : chosen)
      if (keep.back() != i) keep.push_back(i);
  }
  if (keep.back() != y.size() - 1) keep.push_back(y.size() - 1);
  return keep;
}

std::string xml_escape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
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
        out += c;
    }
  }
  return out;
}

std::string render_svg(const std::vector<Panel>& panels, const FigureOptions& options) {
  const int columns = std::max(1, options.columns);
  const int rows = int((panels.size() + std::size_t(columns) - 1) / std::size_t(columns));
  const double title_h = options.title.empty() ? 4 : 30;
  const double panel_w = double(options.width) / columns;
  const double height = title_h + rows * double(options.panel_height);
  std::string out;
  out += "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  out += "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"" + std::to_string(options.width) +
         "\" height=\"" + fmt("%.0f", height) + "\" viewBox=\"0 0 " + std::to_string(options.width) + " " +
         fmt("%.0f", height) + "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  out += "<rect width=\"100%\" height=\"100%\" fill=\"#ffffff\"/>\n";
  if (!options.title.empty())
    out += "<text x=\"" + fmt("%.1f", options.width / 2.0) +
           "\" y=\"20\" text-anchor=\"middle\" font-size=\"15\" font-weight=\"bold\">" + xml_escape(options.title) +
           "</text>\n";
  for (std::size_t i = 0; i < panels.size(); ++i) {
    const double left = double(i % std::size_t(columns)) * panel_w;
    const double top = title_h + double(i / std::size_t(columns)) * options.panel_height;
    draw_panel(out, panels[i], left, top, panel_w, options.panel_height, options.max_points);
  }
  out += "</svg>\n";
  return out;
}

void write_svg(const std::string& path, const std::vector<Panel>& panels, const FigureOptions& options) {
  write_text_atomic(path, render_svg(panels, options));
}

std::string client_color(int k) {
  static const char* const kColors[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd",
                                        "#ff7f0e", "#17becf", "#e377c2", "#bcbd22"};
  return kColors[std::size_t(std::max(0, k - 1)) % (sizeof kColors / sizeof kColors[0])];
}

}  // namespace cslam::report
