#include <gtest/gtest.h>

#include "core/cli.h"
#include "core/error.h"

using cslam::CliArgs;

namespace {
bool parse(CliArgs& a, std::vector<std::string> argv) {
  std::vector<char*> ptrs;
  for (auto& s : argv) ptrs.push_back(s.data());
  return a.parse(int(ptrs.size()), ptrs.data());
}
}  // namespace

TEST(CliArgs, OptionsFlagsPositionals) {
  CliArgs a("prog", "test");
  a.positional("IN", "input").option("voxel", "size", "0.01").flag("json", "json").multi_option("poses", "files");
  ASSERT_TRUE(parse(a, {"prog", "file.txt", "--voxel=0.05", "--json", "--poses", "a", "b"}));
  EXPECT_EQ(a.positionals()[0], "file.txt");
  EXPECT_DOUBLE_EQ(a.get_double("voxel"), 0.05);
  EXPECT_TRUE(a.flag_set("json"));
  EXPECT_EQ(a.get_multi("poses"), (std::vector<std::string>{"a", "b"}));
}

TEST(CliArgs, DefaultsAndErrors) {
  CliArgs a("prog", "test");
  a.option("n", "count", "3").option("out", "required");
  EXPECT_THROW(parse(a, {"prog", "--n", "4"}), cslam::ConfigError);  // --out missing
  CliArgs b("prog", "test");
  b.option("n", "count", "3");
  EXPECT_THROW(parse(b, {"prog", "--bogus", "1"}), cslam::ConfigError);
  CliArgs c("prog", "test");
  c.option("n", "count", "3");
  ASSERT_TRUE(parse(c, {"prog"}));
  EXPECT_EQ(c.get_int("n"), 3);
  CliArgs d("prog", "test");
  d.option("n", "count", "3");
  ASSERT_TRUE(parse(d, {"prog", "--n", "x"}));
  EXPECT_THROW(d.get_int("n"), cslam::ConfigError);
}
