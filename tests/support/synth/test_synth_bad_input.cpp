// Bad input: impossible parameters give a clear error (library: exceptions; program: message and
// non-zero exit), and a failed run leaves no output folder that looks complete.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "core/error.h"
#include "support/synth/dataset_writer.h"
#include "synth_test_util.h"

using namespace cslam;
using namespace cslam::synth;
using cslam::synth::test::TempDir;

namespace {

SynthConfig tiny(const std::string& out) {
  SynthConfig c = synth_preset("test-small");
  c.trajectory.frames = 12;
  c.output.out_dir = out;
  c.output.ply_spacing = 0.05;
  return c;
}

template <class E>
std::string error_of(const SynthConfig& c) {
  try {
    generate_dataset(c);
  } catch (const E& e) {
    return e.what();
  }
  return "<no error>";
}

struct RunResult {
  int exit_code = -1;
  std::string output;
};

RunResult run_synth(const std::string& args) {
  const std::string cmd = std::string(CSLAM_BIN_DIR) + "/cslam-synth " + args + " 2>&1";
  RunResult r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  char buf[512];
  while (fgets(buf, sizeof(buf), p)) r.output += buf;
  const int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

}  // namespace

TEST(SynthBadInput, ImpossibleParametersThrowClearErrors) {
  TempDir tmp;
  SynthConfig c = tiny(tmp / "out");
  c.trajectory.robots = 0;
  EXPECT_NE(error_of<ConfigError>(c).find("at least one robot"), std::string::npos);
  c = tiny(tmp / "out");
  c.scene.width = -8;
  EXPECT_NE(error_of<ConfigError>(c).find("room size must be positive"), std::string::npos);
  c = tiny(tmp / "out");
  c.scene.width = c.scene.depth = 3.0;  // walkway 1.8 m from each wall does not fit
  EXPECT_NE(error_of<ConfigError>(c).find("too small for the robots' trajectories"), std::string::npos);
  c = tiny(tmp / "out");
  c.trajectory.loop = true;  // a full turn within 12 frames breaks the rotation limit
  EXPECT_NE(error_of<ConfigError>(c).find("loop"), std::string::npos);
  c = tiny(tmp / "out");
  c.scene.furniture = 200;
  EXPECT_NE(error_of<ConfigError>(c).find("furniture"), std::string::npos);
  c = tiny(tmp / "out");
  c.camera.dist[0] = 0.1;
  EXPECT_NE(error_of<ConfigError>(c).find("distortion"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(tmp / "out"));
}

TEST(SynthBadInput, UnwritableOrExistingOutputIsAnInputError) {
  TempDir tmp;
  { std::ofstream(tmp / "a_file") << "x"; }
  const std::string msg = error_of<InputError>(tiny(tmp / "a_file/out"));
  EXPECT_NE(msg.find("a_file/out"), std::string::npos) << msg;
  std::filesystem::create_directories(tmp / "exists");
  EXPECT_NE(error_of<InputError>(tiny(tmp / "exists")).find("already exists"), std::string::npos);
}

TEST(SynthBadInput, FailureLeavesNoCompleteLookingFolder) {
  TempDir tmp;
  SynthConfig c = tiny(tmp / "out");
  c.output.ply_spacing = 1e-5;  // rejected after the frames were rendered (too many points)
  EXPECT_NE(error_of<ConfigError>(c).find("too many points"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(tmp / "out"));
  EXPECT_TRUE(std::filesystem::is_empty(tmp.path()));  // the temporary folder is gone too
}

TEST(SynthBadInput, ProgramReportsErrorsWithNonZeroExit) {
  TempDir tmp;
  const RunResult help = run_synth("--help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.output.find("--robots"), std::string::npos);
  const RunResult zero = run_synth("--preset test-small --robots 0 --out " + (tmp / "o1"));
  EXPECT_NE(zero.exit_code, 0);
  EXPECT_NE(zero.output.find("at least one robot"), std::string::npos) << zero.output;
  const RunResult room = run_synth("--preset test-small --room 8x-6x3 --out " + (tmp / "o2"));
  EXPECT_NE(room.exit_code, 0);
  EXPECT_NE(room.output.find("room size must be positive"), std::string::npos) << room.output;
  const RunResult bad_room = run_synth("--preset test-small --room 8x6 --out " + (tmp / "o3"));
  EXPECT_NE(bad_room.exit_code, 0);
  EXPECT_NE(bad_room.output.find("WxDxH"), std::string::npos) << bad_room.output;
  const RunResult preset = run_synth("--preset nope --out " + (tmp / "o4"));
  EXPECT_NE(preset.exit_code, 0);
  EXPECT_NE(preset.output.find("unknown preset"), std::string::npos);
  EXPECT_TRUE(std::filesystem::is_empty(tmp.path()));
  // And a good small run works end to end.
  const RunResult ok = run_synth("--preset test-small --frames 12 --ply-spacing 0.05 --out " + (tmp / "ok"));
  EXPECT_EQ(ok.exit_code, 0) << ok.output;
  EXPECT_TRUE(std::filesystem::exists(tmp / "ok/robot_2/groundtruth.txt"));
  EXPECT_TRUE(std::filesystem::exists(tmp / "ok/scene.json"));
}
