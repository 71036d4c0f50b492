// Flow frames (tracking/frame_flow.h): the previous frame's keypoints followed into a new image by
// pyramidal Lucas-Kanade, with their octave, angle and descriptor carried and depth read anew.
#include <algorithm>
#include <cmath>
#include <cstdint>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "slam/features/orb_extractor.h"
#include "slam/features/procedural_image.h"
#include "slam/tracking/frame_flow.h"

using namespace cslam;

namespace {

struct Scene {
  PinholeCamera camera;  // 640x480, no distortion
  OrbExtractor extractor;
  std::shared_ptr<const ScalePyramid> pyramid = ScalePyramid::from(extractor);
  cv::Mat texture = procedural_image(17, {1200, 900});
  // A view shifted by (dx, dy) pixels (sub-pixel, bilinear) and its constant-depth image.
  cv::Mat view(double dx, double dy) const {
    const cv::Mat gray = render_view(texture, 600 - dx, 450 - dy, 0.0, 1.0);
    cv::Mat bgr;
    cv::cvtColor(gray, bgr, cv::COLOR_GRAY2BGR);
    return bgr;
  }
  cv::Mat depth(double metres) const { return cv::Mat(480, 640, CV_16UC1, cv::Scalar(metres * camera.depth_factor)); }
};

}  // namespace

TEST(FrameFlow, FollowsKeypointsThroughASubPixelShiftAndCarriesTheirFeatures) {
  const Scene s;
  const cv::Mat a = s.view(0, 0), b = s.view(3.4, -2.2);
  const auto prev =
      make_frame_data(FrameId{1, 1}, 0.0, a, s.depth(2.0), s.camera, RgbdParams{}, s.extractor, s.pyramid, nullptr);
  ASSERT_GT(prev->size(), 300u);
  FlowConfig config;
  cv::Mat ga, gb;
  cv::cvtColor(a, ga, cv::COLOR_BGR2GRAY);
  cv::cvtColor(b, gb, cv::COLOR_BGR2GRAY);
  const FlowPyramid pa = build_flow_pyramid(ga, config), pb = build_flow_pyramid(gb, config);
  FlowSeeds seeds;
  for (std::size_t i = 0; i < prev->size(); ++i) {
    seeds.index.push_back(int(i));
    // The motion model's guess is a pixel off: the flow must still land on the true shift.
    seeds.predicted.push_back(prev->features.keypoints[i].pt + cv::Point2f(4.2f, -1.5f));
  }
  const FlowFrame f = make_flow_frame(FrameId{1, 2}, 0.033, b, s.depth(1.5), *prev, pa, pb, seeds, config, nullptr, 4,
                                      std::nullopt, std::nullopt, true);
  ASSERT_EQ(f.data->size(), f.previous_index.size());
  ASSERT_GT(f.data->size(), prev->size() * 9 / 10);
  int close = 0;
  std::vector<double> errors;
  for (std::size_t k = 0; k < f.data->size(); ++k) {
    const auto& was = prev->features.keypoints[std::size_t(f.previous_index[k])];
    const auto& now = f.data->features.keypoints[k];
    const double ex = now.pt.x - (was.pt.x + 3.4), ey = now.pt.y - (was.pt.y - 2.2);
    if (std::hypot(ex, ey) < 0.15) ++close;
    errors.push_back(std::hypot(ex, ey));
    EXPECT_EQ(now.octave, was.octave);
    EXPECT_EQ(now.angle, was.angle);
    EXPECT_EQ(f.data->features.descriptors[k], prev->features.descriptors[std::size_t(f.previous_index[k])]);
    EXPECT_NEAR(f.data->features.undistorted[k].x(), now.pt.x, 1e-6);  // no distortion
    if (f.data->depth[k] > 0) {
      EXPECT_NEAR(f.data->depth[k], 1.5, 1e-3);  // read in the new depth image
    }
  }
  std::sort(errors.begin(), errors.end());
  // Measured: median 0.06 px, 90th percentile 0.20 px, a few wrong tracks (the pose
  // optimisation's robust kernel and the outlier test deal with those).
  EXPECT_LT(errors[errors.size() / 2], 0.1);
  EXPECT_LT(errors[errors.size() * 9 / 10], 0.3);
  EXPECT_GT(close, int(f.data->size()) * 3 / 4);
  EXPECT_LT(errors[errors.size() * 97 / 100], 1.0);
  EXPECT_FALSE(f.data->pending_bow.vocabulary);
  EXPECT_TRUE(f.data->keyframe_depth);
}

TEST(FrameFlow, DropsTracksThatLeaveTheImageOrFail) {
  const Scene s;
  const cv::Mat a = s.view(0, 0), b = s.view(40, 0);  // 40 px to the right: the right edge's points leave
  const auto prev =
      make_frame_data(FrameId{1, 1}, 0.0, a, s.depth(2.0), s.camera, RgbdParams{}, s.extractor, s.pyramid, nullptr);
  FlowConfig config;
  cv::Mat ga, gb;
  cv::cvtColor(a, ga, cv::COLOR_BGR2GRAY);
  cv::cvtColor(b, gb, cv::COLOR_BGR2GRAY);
  FlowSeeds seeds;
  int leaving = 0;
  for (std::size_t i = 0; i < prev->size(); ++i) {
    seeds.index.push_back(int(i));
    seeds.predicted.push_back(prev->features.keypoints[i].pt + cv::Point2f(40, 0));
    if (prev->features.keypoints[i].pt.x + 40 >= 640) ++leaving;
  }
  ASSERT_GT(leaving, 10);
  const FlowFrame f =
      make_flow_frame(FrameId{1, 2}, 0.033, b, cv::Mat(), *prev, build_flow_pyramid(ga, config),
                      build_flow_pyramid(gb, config), seeds, config, nullptr, 4, std::nullopt, std::nullopt, true);
  for (std::size_t k = 0; k < f.data->size(); ++k) {
    EXPECT_LT(f.data->features.keypoints[k].pt.x, 640.0f);
    EXPECT_LT(f.data->depth[k], 0.0f);  // no depth image: no depth
  }
  EXPECT_LE(f.data->size(), prev->size() - std::size_t(leaving));
  EXPECT_FALSE(f.data->keyframe_depth);  // a frame without depth never becomes a keyframe

  // A black image: nothing to follow, and no crash.
  const cv::Mat black(480, 640, CV_8UC1, cv::Scalar(0));
  cv::Mat black_bgr;
  cv::cvtColor(black, black_bgr, cv::COLOR_GRAY2BGR);
  const FlowFrame none =
      make_flow_frame(FrameId{1, 3}, 0.066, black_bgr, cv::Mat(), *prev, build_flow_pyramid(ga, config),
                      build_flow_pyramid(black, config), seeds, config, nullptr, 4, std::nullopt, std::nullopt, true);
  EXPECT_LT(none.data->size(), prev->size() / 2);
}

TEST(FrameFlow, ModesParseAndConfigIsValidated) {
  EXPECT_EQ(parse_flow_mode("off"), FlowMode::kOff);
  EXPECT_EQ(parse_flow_mode("under-load"), FlowMode::kUnderLoad);
  EXPECT_EQ(parse_flow_mode("always"), FlowMode::kAlways);
  EXPECT_THROW(parse_flow_mode("sometimes"), ConfigError);
  EXPECT_NO_THROW(FlowConfig{}.validate());
  FlowConfig even;
  even.window = 8;
  EXPECT_THROW(even.validate(), ConfigError);
  FlowConfig calib;
  calib.calibration_min = calib.calibration_window + 1;
  EXPECT_THROW(calib.validate(), ConfigError);
}
