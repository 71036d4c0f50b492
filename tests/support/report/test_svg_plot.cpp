#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include <gtest/gtest.h>

#include "common/run_program.h"
#include "support/report/svg_plot.h"
#include "support/report/xml_check.h"

using namespace cslam::report;
using cslam::test::xml_wellformed_error;

namespace {

int count(const std::string& text, const std::string& what) {
  int n = 0;
  for (std::size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

Panel sine_panel(std::size_t n) {
  Panel p;
  p.title = "APE <m> & \"errors\"";
  p.x_label = "time (s)";
  p.y_label = "APE (m)";
  Series s;
  s.label = "client 1";
  for (std::size_t i = 0; i < n; ++i) {
    s.x.push_back(double(i) * 0.1);
    s.y.push_back(std::sin(double(i) * 0.05));
  }
  p.series.push_back(s);
  p.markers.push_back({1.0, 0.5, "#ff0000", "F1"});
  p.vlines.push_back({2.0, "#000000", "c2+c1"});
  return p;
}

}  // namespace

TEST(NiceTicks, CoverTheRangeWithRoundSteps) {
  const auto t = nice_ticks(0.013, 0.87, 5);
  ASSERT_GE(t.size(), 3u);
  EXPECT_GE(t.front(), 0.013 - 1e-12);
  EXPECT_LE(t.back(), 0.87 + 1e-12);
  const double step = t[1] - t[0];
  EXPECT_NEAR(step, 0.2, 1e-12);
  for (std::size_t i = 1; i < t.size(); ++i) EXPECT_NEAR(t[i] - t[i - 1], step, 1e-9);
  EXPECT_EQ(nice_ticks(-3, -3).size(), 0u);
  EXPECT_EQ(nice_ticks(std::nan(""), 1).size(), 0u);
  const auto z = nice_ticks(-1.0, 1.0, 4);
  EXPECT_NE(std::find(z.begin(), z.end(), 0.0), z.end());  // zero exactly, not 1e-17
}

TEST(Decimate, KeepsEndsAndExtremes) {
  std::vector<double> y(10000, 1.0);
  y[1234] = 50.0;   // a spike
  y[7777] = -20.0;  // a dip
  const auto keep = decimate_min_max(y, 200);
  EXPECT_LE(keep.size(), 200u);
  EXPECT_EQ(keep.front(), 0u);
  EXPECT_EQ(keep.back(), y.size() - 1);
  EXPECT_NE(std::find(keep.begin(), keep.end(), 1234u), keep.end());
  EXPECT_NE(std::find(keep.begin(), keep.end(), 7777u), keep.end());
  EXPECT_TRUE(std::is_sorted(keep.begin(), keep.end()));
  EXPECT_EQ(decimate_min_max(std::vector<double>(50, 0.0), 200).size(), 50u);
}

TEST(Decimate, KeepsAGapInsideABucket) {
  std::vector<double> y(1000, 2.0);
  y[500] = std::numeric_limits<double>::quiet_NaN();
  const auto keep = decimate_min_max(y, 40);
  EXPECT_NE(std::find(keep.begin(), keep.end(), 500u), keep.end());
}

TEST(SvgPlot, WellFormedWithEscapedTextAndEveryElement) {
  FigureOptions o;
  o.title = "fig <1>";
  const std::string svg = render_svg({sine_panel(100), sine_panel(3)}, o);
  EXPECT_EQ(xml_wellformed_error(svg), "") << svg.substr(0, 2000);
  EXPECT_NE(svg.find("APE &lt;m&gt; &amp; &quot;errors&quot;"), std::string::npos);
  EXPECT_NE(svg.find("fig &lt;1&gt;"), std::string::npos);
  EXPECT_NE(svg.find("c2+c1"), std::string::npos);
  EXPECT_NE(svg.find("map fusion"), std::string::npos);  // legend entry for the markers
  EXPECT_EQ(count(svg, "<clipPath"), 2);
}

TEST(SvgPlot, NanBreaksTheLine) {
  Panel p;
  Series s;
  s.x = {0, 1, 2, 3, 4};
  s.y = {0, 1, std::nan(""), 3, 4};
  p.series.push_back(s);
  const std::string svg = render_svg({p}, {});
  // Two sub-paths: M..L.. then M..L..
  const auto d = svg.find("<path d=\"M", svg.find("clip-path"));
  ASSERT_NE(d, std::string::npos);
  const std::string path = svg.substr(d, svg.find('"', d + 9) - d);
  EXPECT_EQ(count(path, "M"), 2) << path;
  EXPECT_EQ(xml_wellformed_error(svg), "");
}

TEST(SvgPlot, EmptyPanelsAndFlatDataStillRender) {
  Panel empty;
  empty.title = "nothing";
  Panel flat;
  Series s;
  s.x = {1, 1, 1};
  s.y = {5, 5, 5};
  flat.series.push_back(s);
  flat.equal_aspect = true;
  Panel bars;
  Series b;
  b.x = {0.5, 2.5, 5};
  b.y = {1, 2, 3};
  b.y_low = {0.5, 1.5, 2.5};
  b.y_high = {1.5, 2.5, 3.5};
  b.marker_radius = 3;
  bars.series.push_back(b);
  FigureOptions o;
  o.columns = 2;
  const std::string svg = render_svg({empty, flat, bars}, o);
  EXPECT_EQ(xml_wellformed_error(svg), "");
  EXPECT_NE(svg.find("no data"), std::string::npos);
  EXPECT_EQ(svg.find("nan"), std::string::npos);
  EXPECT_EQ(svg.find("inf"), std::string::npos);
}

TEST(SvgPlot, DecimatesLongSeries) {
  FigureOptions o;
  o.max_points = 100;
  const std::string svg = render_svg({sine_panel(20000)}, o);
  EXPECT_LT(svg.size(), 20000u);
  EXPECT_EQ(xml_wellformed_error(svg), "");
}

TEST(SvgPlot, WritesTheFileAtomically) {
  cslam::test::TempDir dir("cslam_svg");
  write_svg(dir / "a.svg", {sine_panel(10)}, {});
  std::ifstream in(dir / "a.svg");
  std::stringstream ss;
  ss << in.rdbuf();
  EXPECT_EQ(xml_wellformed_error(ss.str()), "");
  EXPECT_THROW(write_svg(dir / "missing/a.svg", {sine_panel(10)}, {}), std::exception);
}

TEST(XmlCheck, RejectsBrokenDocuments) {
  EXPECT_EQ(xml_wellformed_error("<svg><g/></svg>"), "");
  EXPECT_NE(xml_wellformed_error("<svg><g></svg>"), "");
  EXPECT_NE(xml_wellformed_error("<svg a=1></svg>"), "");
  EXPECT_NE(xml_wellformed_error("<svg>a & b</svg>"), "");
  EXPECT_NE(xml_wellformed_error("<svg></svg><svg></svg>"), "");
  EXPECT_NE(xml_wellformed_error("<svg>"), "");
  EXPECT_NE(xml_wellformed_error(""), "");
}
