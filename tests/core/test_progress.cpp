// Progress lines: their text, and plain lines vs in-place redraws (no clock assertions: the
// intervals are 0 or huge so what is printed does not depend on the machine's speed).
#include <algorithm>
#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "core/progress.h"

namespace cslam {
namespace {

std::string read_all(std::FILE* f) {
  std::rewind(f);
  std::string s;
  char buf[256];
  while (std::size_t n = std::fread(buf, 1, sizeof buf, f)) s.append(buf, n);
  return s;
}

TEST(Progress, FormatsCountRateAndEta) {
  EXPECT_EQ(Progress::format("client 1: sent", 30, 60, "frames", 10.0, "94.3 KB/frame"),
            "client 1: sent 30/60 frames (50.0 %), 10.0 frames/s, ETA 3 s, 94.3 KB/frame");
  EXPECT_EQ(Progress::format("runs", 5, 0, "runs", 0.5, ""), "runs 5 runs, 2 s each");
  EXPECT_EQ(Progress::format("runs", 1, 4, "runs", 1.0 / 125, ""),
            "runs 1/4 runs (25.0 %), 2 min 05 s each, ETA 6 min 15 s");
  EXPECT_EQ(Progress::format("x", 0, 10, "f", 0.0, ""), "x 0/10 f (0.0 %), 0.0 f/s, ETA ?");
  EXPECT_EQ(Progress::format("x", 10, 10, "f", 2.0, ""), "x 10/10 f (100.0 %), 2.0 f/s");
}

TEST(Progress, FormatsDurations) {
  EXPECT_EQ(format_duration(42.4), "42 s");
  EXPECT_EQ(format_duration(185), "3 min 05 s");
  EXPECT_EQ(format_duration(3720), "1 h 02 min");
  EXPECT_EQ(format_duration(-1), "?");
}

TEST(Progress, PlainLinesWhenNotATerminal) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  {
    ProgressOptions o;
    o.terminal = 0;
    o.interval_s = 0.0;  // every update prints
    Progress p("sent", 3, "frames", o, f);
    EXPECT_FALSE(p.terminal());
    p.update(1);
    p.update(3);
    p.finish();
  }
  const std::string out = read_all(f);
  std::fclose(f);
  EXPECT_EQ(out.find('\r'), std::string::npos);
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 3);
  EXPECT_NE(out.find("sent 1/3 frames"), std::string::npos);
  EXPECT_NE(out.find("sent 3/3 frames (100.0 %)"), std::string::npos);
  EXPECT_NE(out.find("done in"), std::string::npos);
}

TEST(Progress, NothingBeforeTheIntervalButAlwaysAFinalLine) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  {
    ProgressOptions o;
    o.terminal = 0;
    o.interval_s = 1e9;
    Progress p("fused", 100, "frames", o, f);
    for (int i = 1; i <= 100; ++i) p.update(i);
    p.finish();
  }
  const std::string out = read_all(f);
  std::fclose(f);
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1);
  EXPECT_EQ(out.rfind("fused 100/100 frames (100.0 %)", 0), 0u);
}

TEST(Progress, RedrawsInPlaceOnATerminal) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  {
    ProgressOptions o;
    o.terminal = 1;
    o.redraw_s = 0.0;
    Progress p("sent", 2, "frames", o, f);
    p.update(1);
    p.update(2);
    p.finish();
  }
  const std::string out = read_all(f);
  std::fclose(f);
  EXPECT_EQ(std::count(out.begin(), out.end(), '\r'), 3);
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1);  // only the final line ends the line
  EXPECT_EQ(out.back(), '\n');
}

}  // namespace
}  // namespace cslam
