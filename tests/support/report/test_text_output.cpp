#include <cmath>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "common/run_program.h"
#include "support/report/text_output.h"

using namespace cslam::report;

TEST(Markdown, HeaderAlignmentAndEscapedCells) {
  Table t;
  t.header = {"config", "ATE (m)"};
  t.align = {'l', 'r'};
  t.rows = {{"2 | clients", "0.0206"}, {"single"}};
  EXPECT_EQ(to_markdown(t),
            "| config | ATE (m) |\n"
            "|---|---:|\n"
            "| 2 \\| clients | 0.0206 |\n"
            "| single |  |\n");
}

TEST(Csv, QuotesOnlyWhenNeeded) {
  EXPECT_EQ(csv_field("plain"), "plain");
  EXPECT_EQ(csv_field("a,b"), "\"a,b\"");
  EXPECT_EQ(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(csv_field("two\nlines"), "\"two\nlines\"");
  Table t;
  t.header = {"a", "b"};
  t.rows = {{"1", "x,y"}, {"2"}};
  EXPECT_EQ(to_csv(t), "a,b\n1,\"x,y\"\n2,\n");
}

TEST(Numbers, MissingValuesAreNa) {
  EXPECT_EQ(format_number(0.020649, 4), "0.0206");
  EXPECT_EQ(format_number(std::nan(""), 3), "n/a");
  EXPECT_EQ(format_number(INFINITY, 3), "n/a");
}

TEST(Spread, MedianAndRangeIgnoringNan) {
  const Spread s = spread({3.0, std::nan(""), 1.0, 2.0, 10.0});
  EXPECT_EQ(s.n, 4);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.min, 1.0);
  EXPECT_DOUBLE_EQ(s.max, 10.0);
  EXPECT_EQ(format_spread(s, 2), "2.50 (1.00–10.00)");
  EXPECT_EQ(format_spread(spread({}), 2), "n/a");
  EXPECT_EQ(format_spread(spread({0.5}), 1), "0.5");
  EXPECT_EQ(format_spread(spread({0.501, 0.499}), 1), "0.5");
}

TEST(WriteText, AtomicAndNamesThePathOnFailure) {
  cslam::test::TempDir dir("cslam_text_out");
  write_text_atomic(dir / "r.md", "hello\n");
  std::ifstream in(dir / "r.md");
  std::stringstream ss;
  ss << in.rdbuf();
  EXPECT_EQ(ss.str(), "hello\n");
  try {
    write_text_atomic(dir / "no/such/dir/r.md", "x");
    FAIL() << "expected an error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("no/such/dir/r.md"), std::string::npos) << e.what();
  }
}
