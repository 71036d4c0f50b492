// End-to-end: cslam-vocab trains a tiny vocabulary from procedural images, info reads it back,
// and a corrupt file gives a one-line error naming it.
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "slam/bow/vocabulary.h"

namespace cslam {
namespace {

std::string run(const std::string& cmd, int& rc) {
  const std::string out_file = ::testing::TempDir() + "/cslam_vocab_cli.out";
  rc = std::system((cmd + " > " + out_file + " 2>&1").c_str());
  std::ifstream in(out_file);
  return std::string((std::istreambuf_iterator<char>(in)), {});
}

TEST(VocabCli, TrainInfoAndCorruptFile) {
  const std::string bin = std::string(CSLAM_BIN_DIR) + "/cslam-vocab";
  const std::string voc = ::testing::TempDir() + "/cslam_cli_test.voc";
  int rc = 0;
  std::string out =
      run(bin + " train --synthetic-images 4 --features 200 --branching 5 --depth 3 --threads 2 --out " + voc, rc);
  ASSERT_EQ(rc, 0) << out;
  const Vocabulary v = Vocabulary::load(voc);
  EXPECT_EQ(v.branching(), 5);
  EXPECT_EQ(v.depth(), 3);
  EXPECT_GT(v.num_words(), 50u);
  out = run(bin + " info " + voc, rc);
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("branching   5"), std::string::npos) << out;
  EXPECT_NE(out.find("words       " + std::to_string(v.num_words())), std::string::npos) << out;

  {
    std::fstream f(voc, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(100);
    f.put('\x5a');
  }
  out = run(bin + " info " + voc, rc);
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find(voc + ": vocabulary checksum mismatch"), std::string::npos) << out;
  out = run(bin + " train --out " + voc, rc);
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("no images"), std::string::npos) << out;
  std::remove(voc.c_str());
  std::remove((::testing::TempDir() + "/cslam_vocab_cli.out").c_str());
}

}  // namespace
}  // namespace cslam
