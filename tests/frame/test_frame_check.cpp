// The one definition of a well-formed frame (frame/frame_check.h): every way a frame can fail to
// fit its camera is named, and every frame a camera produces passes.
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "common/small_camera.h"
#include "frame/frame_check.h"

using namespace cslam;

namespace {

PinholeCamera camera() { return test::small_camera(); }  // 160 x 120

RgbdFrame good() {
  const PinholeCamera c = camera();
  RgbdFrame f;
  f.timestamp = 12.5;
  f.bgr = test::plane_colour(c);
  f.depth = test::plane_depth(c, 1.5);
  return f;
}

bool says(const std::string& why, const char* what) { return why.find(what) != std::string::npos; }

}  // namespace

TEST(FrameCheck, WellFormedFramesPass) {
  EXPECT_EQ(frame_problem(good(), camera()), "");
  RgbdFrame colour_only = good();
  colour_only.depth = cv::Mat();
  EXPECT_EQ(frame_problem(colour_only, camera()), "");
  RgbdFrame offset = good();
  offset.depth_time_offset = -kMaxDepthTimeOffset;
  EXPECT_EQ(frame_problem(offset, camera()), "");
  RgbdFrame light = good();
  light.depth_subsample = 4;
  EXPECT_EQ(frame_problem(light, camera()), "");
}

TEST(FrameCheck, NamesEachProblem) {
  RgbdFrame f = good();
  f.bgr = cv::Mat(100, 160, CV_8UC3);
  EXPECT_TRUE(says(frame_problem(f, camera()), "colour image is not 160x120")) << frame_problem(f, camera());
  f = good();
  f.bgr = cv::Mat(120, 160, CV_8UC1);
  EXPECT_TRUE(says(frame_problem(f, camera()), "colour"));
  f = good();
  f.bgr = cv::Mat();
  EXPECT_TRUE(says(frame_problem(f, camera()), "colour"));
  f = good();
  f.depth = cv::Mat(120, 160, CV_32FC1);
  EXPECT_TRUE(says(frame_problem(f, camera()), "depth image is not 160x120 16-bit"));
  f = good();
  f.depth = cv::Mat(120, 80, CV_16UC1);
  EXPECT_TRUE(says(frame_problem(f, camera()), "depth image is not"));
  f = good();
  f.depth_subsample = 0;
  EXPECT_TRUE(says(frame_problem(f, camera()), "subsample"));
  f = good();
  f.timestamp = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(says(frame_problem(f, camera()), "timestamp"));
  for (double offset : {0.5, -0.2, std::nan("")}) {  // a depth image that cannot be this frame's
    f = good();
    f.depth_time_offset = offset;
    EXPECT_TRUE(says(frame_problem(f, camera()), "from the colour image")) << offset;
  }
}
