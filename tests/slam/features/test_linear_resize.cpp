// resize_linear against cv::resize(INTER_LINEAR): the same pixels for the ORB pyramid's sizes,
// odd sizes, views into larger images and real-looking content.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <opencv2/imgproc.hpp>

#include "slam/features/linear_resize.h"
#include "slam/features/procedural_image.h"
#include "slam/features/noise_image.h"

namespace cslam {
namespace {

int differing_pixels(const cv::Mat& image, cv::Size to, const LinearResize& rule) {
  cv::Mat expected, actual;
  cv::resize(image, expected, to, 0, 0, cv::INTER_LINEAR);
  resize_linear(image, actual, to, rule);
  if (actual.size() != to || actual.type() != CV_8UC1) return -1;
  return cv::countNonZero(actual != expected);
}

TEST(LinearResize, TheLinkedOpenCvIsReproduced) {
  const LinearResize* rule = opencv_linear_resize();
  ASSERT_NE(rule, nullptr) << "no vector width reproduces cv::resize";
  const auto probed = probe_opencv_linear_resize();
  ASSERT_NE(probed, nullptr);
  EXPECT_EQ(probed->vector_columns, rule->vector_columns);
}

TEST(LinearResize, OrbPyramidOfNoiseAndScenes) {
  const LinearResize* rule = opencv_linear_resize();
  ASSERT_NE(rule, nullptr);
  for (const cv::Size base : {cv::Size(640, 480), cv::Size(320, 240), cv::Size(752, 480), cv::Size(1241, 376)}) {
    for (unsigned seed : {1u, 2u}) {
      ProceduralImageConfig scene;
      scene.width = base.width;
      scene.height = base.height;
      cv::Mat level = seed == 1 ? noise_image(base, 11) : procedural_image(5, scene);
      for (int l = 1; l < 8; ++l) {
        const cv::Size size(int(std::lround(base.width / std::pow(1.2, l))),
                            int(std::lround(base.height / std::pow(1.2, l))));
        ASSERT_EQ(differing_pixels(level, size, *rule), 0) << base << " level " << l << " seed " << seed;
        cv::resize(level, level, size, 0, 0, cv::INTER_LINEAR);
      }
    }
  }
}

TEST(LinearResize, EverySmallSize) {
  const LinearResize* rule = opencv_linear_resize();
  ASSERT_NE(rule, nullptr);
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> side(1, 70);
  for (int k = 0; k < 400; ++k) {
    const cv::Size from(side(rng), side(rng));
    const cv::Size to(1 + side(rng) % from.width, 1 + side(rng) % from.height);
    ASSERT_EQ(differing_pixels(noise_image(from, unsigned(k)), to, *rule), 0) << from << " -> " << to;
  }
  // Every width from 1 to 80 (each remainder of every vector width) down by 1.2, and to the same size.
  for (int w = 1; w <= 80; ++w) {
    const cv::Mat image = noise_image(cv::Size(w, 9), unsigned(w));
    ASSERT_EQ(differing_pixels(image, cv::Size(std::max(1, int(std::lround(w / 1.2))), 7), *rule), 0) << w;
    ASSERT_EQ(differing_pixels(image, image.size(), *rule), 0) << w;
  }
}

TEST(LinearResize, ViewIntoALargerImageAndExtremeValues) {
  const LinearResize* rule = opencv_linear_resize();
  ASSERT_NE(rule, nullptr);
  const cv::Mat big = noise_image(cv::Size(700, 500), 9);
  const cv::Mat view = big(cv::Rect(13, 7, 640, 480));
  EXPECT_EQ(differing_pixels(view, cv::Size(533, 400), *rule), 0);
  // Saturated and alternating extremes: the largest fixed-point sums.
  cv::Mat extremes(101, 203, CV_8UC1);
  for (int y = 0; y < extremes.rows; ++y)
    for (int x = 0; x < extremes.cols; ++x) extremes.at<std::uint8_t>(y, x) = ((x + y) % 3 == 0) ? 255 : 0;
  EXPECT_EQ(differing_pixels(extremes, cv::Size(169, 84), *rule), 0);
  EXPECT_EQ(differing_pixels(cv::Mat(50, 60, CV_8UC1, cv::Scalar(255)), cv::Size(41, 33), *rule), 0);
  // The output may be the input matrix itself.
  cv::Mat same = noise_image(cv::Size(640, 480), 5), expected;
  cv::resize(same, expected, cv::Size(533, 400), 0, 0, cv::INTER_LINEAR);
  resize_linear(same, same, cv::Size(533, 400), *rule);
  EXPECT_EQ(cv::countNonZero(same != expected), 0);
}

TEST(LinearResize, TheRoundingRuleMatters) {
  // The check can fail: with the other rounding on every column, some pixels differ.
  const LinearResize* rule = opencv_linear_resize();
  ASSERT_NE(rule, nullptr);
  const LinearResize other{rule->vector_columns == 0 ? 1 : 0};
  EXPECT_GT(differing_pixels(noise_image(cv::Size(640, 480), 4), cv::Size(533, 400), other), 100);
}

TEST(LinearResize, RejectsOtherTypesEmptyAndLargerSizes) {
  const LinearResize rule;
  cv::Mat out;
  EXPECT_THROW(resize_linear(cv::Mat(10, 10, CV_8UC3), out, cv::Size(5, 5), rule), std::invalid_argument);
  EXPECT_THROW(resize_linear(cv::Mat(10, 10, CV_8UC1), out, cv::Size(0, 5), rule), std::invalid_argument);
  EXPECT_THROW(resize_linear(cv::Mat(), out, cv::Size(5, 5), rule), std::invalid_argument);
  EXPECT_THROW(resize_linear(cv::Mat(10, 10, CV_8UC1), out, cv::Size(11, 5), rule), std::invalid_argument);
}

}  // namespace
}  // namespace cslam
