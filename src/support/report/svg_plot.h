#pragma once
// A small SVG line-plot writer for experiment reports: panels of line series (NaN breaks a line),
// optional min-max error bars, point markers and labelled vertical lines, axes with "nice" ticks,
// a legend. No dependencies; the output is plain SVG 1.1 that any browser or viewer shows.
#include <cstddef>
#include <limits>
#include <string>
#include <vector>

namespace cslam::report {

struct Series {
  std::string label;  // legend text (empty: not in the legend)
  std::string color = "#1f77b4";
  std::vector<double> x, y;  // same length; a NaN in y (or x) breaks the line
  double width = 1.5;        // stroke width in px
  bool dashed = false;
  bool line = true;                   // false: markers only
  double marker_radius = 0;           // > 0: a dot at every (kept) point
  std::vector<double> y_low, y_high;  // optional error bars (same length as y)
};

// A point of interest (e.g. a map fusion), drawn as a diamond with an optional short label.
struct Marker {
  double x = 0, y = 0;
  std::string color = "#000000";
  std::string label;
};

// A vertical line across the panel (e.g. the moment of a fusion), labelled at the top.
struct VLine {
  double x = 0;
  std::string color = "#000000";
  std::string label;
};

struct Panel {
  std::string title, x_label, y_label;
  std::vector<Series> series;
  std::vector<Marker> markers;
  std::vector<VLine> vlines;
  bool equal_aspect = false;                                // same metres per pixel on both axes (X-Y trajectories)
  bool y_from_zero = false;                                 // include y = 0 in the range (errors, times)
  double x_min = std::numeric_limits<double>::quiet_NaN();  // fixed x range where finite
  double x_max = std::numeric_limits<double>::quiet_NaN();
};

struct FigureOptions {
  std::string title;
  int width = 900;               // px, whole figure
  int panel_height = 300;        // px, each panel
  int columns = 1;               // panels per row
  std::size_t max_points = 400;  // per series; longer series are decimated keeping each bucket's min and max
};

// Tick positions (multiples of 1, 2 or 5 times a power of ten) covering [lo, hi], about `target` of them.
std::vector<double> nice_ticks(double lo, double hi, int target = 6);

// Indices to keep so that at most max_points remain: the first and last point, and per bucket the
// points with the smallest and largest y (so spikes survive). Returns all indices if short enough.
std::vector<std::size_t> decimate_min_max(const std::vector<double>& y, std::size_t max_points);

// Escapes &, <, >, " and ' for XML text and attribute values.
std::string xml_escape(const std::string& text);

// The whole figure as SVG text. Panels without any finite data get a "no data" note.
std::string render_svg(const std::vector<Panel>& panels, const FigureOptions& options);

// Writes render_svg() to path atomically (temp file + rename). Throws InputError if it cannot.
void write_svg(const std::string& path, const std::vector<Panel>& panels, const FigureOptions& options);

// Colours for client k (1-based) and for ground truth, consistent across every report figure.
std::string client_color(int k);
inline const char* kGroundTruthColor = "#8c8c8c";

}  // namespace cslam::report
