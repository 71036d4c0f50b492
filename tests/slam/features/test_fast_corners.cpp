// detect_fast_corners against cv::FAST(image, keypoints, threshold, true): the same keypoints
// (position, response, size, angle) in the same order, from each implementation (AVX2 where the
// CPU has it, SSE2, pixel by pixel), over procedural scenes, noise of several
// strengths (dense corners at low thresholds), flat and saturated images, narrow images, views
// into larger images and every threshold ORB uses and more; the per-pixel score against the
// definition (the highest threshold at which cv::FAST still reports the pixel without
// suppression).
#include <algorithm>
#include <array>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "slam/features/fast_corners.h"
#include "slam/features/procedural_image.h"

namespace {

std::vector<cslam::FastCornersPath> paths() {
  std::vector<cslam::FastCornersPath> out{cslam::FastCornersPath::kSse2, cslam::FastCornersPath::kScalar};
  if (cslam::fast_corners_best_path() == cslam::FastCornersPath::kAvx2) out.push_back(cslam::FastCornersPath::kAvx2);
  return out;
}

void expect_same_as_opencv(const cv::Mat& image, int threshold, const std::string& what) {
  std::vector<cv::KeyPoint> expected;
  cv::FAST(image, expected, threshold, true);
  for (cslam::FastCornersPath path : paths()) {
    std::vector<cv::KeyPoint> got;
    cslam::detect_fast_corners(image, threshold, got, path);
    ASSERT_EQ(got.size(), expected.size()) << what << " threshold " << threshold << " path " << int(path);
    for (std::size_t i = 0; i < got.size(); ++i) {
      ASSERT_EQ(got[i].pt, expected[i].pt) << what << " threshold " << threshold << " keypoint " << i;
      ASSERT_EQ(got[i].response, expected[i].response) << what << " at " << got[i].pt;
      ASSERT_EQ(got[i].size, expected[i].size);
      ASSERT_EQ(got[i].angle, expected[i].angle);
      ASSERT_EQ(got[i].octave, expected[i].octave);
    }
  }
}

cv::Mat noise(int w, int h, double sigma, double blur, std::uint64_t seed) {
  cv::Mat f(h, w, CV_32F);
  cv::RNG rng(seed);
  rng.fill(f, cv::RNG::NORMAL, 128.0, sigma);
  if (blur > 0) cv::GaussianBlur(f, f, cv::Size(0, 0), blur);
  cv::Mat out;
  f.convertTo(out, CV_8U);
  return out;
}

}  // namespace

TEST(FastCorners, SameAsOpenCvOnScenes) {
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    const cv::Mat scene = cslam::procedural_image(seed);
    for (int t : {1, 5, 7, 12, 20, 40, 80})
      ASSERT_NO_FATAL_FAILURE(expect_same_as_opencv(scene, t, "scene " + std::to_string(seed)));
  }
}

TEST(FastCorners, SameAsOpenCvOnNoise) {
  // From sparse to nearly every pixel a corner; sigma 120 saturates at 0 and 255.
  for (double sigma : {3.0, 10.0, 40.0, 120.0})
    for (double blur : {0.0, 1.0, 2.5})
      for (int t : {0, 1, 7, 20, 60, 200, 255})
        ASSERT_NO_FATAL_FAILURE(expect_same_as_opencv(noise(203, 77, sigma, blur, 7), t,
                                                      "noise " + std::to_string(sigma) + "/" + std::to_string(blur)));
}

TEST(FastCorners, SameAsOpenCvOnEdgeCases) {
  for (int t : {1, 7, 20}) {
    for (int w : {1, 6, 7, 8, 21, 22, 23, 38, 39, 40, 41, 64}) {
      for (int h : {1, 6, 7, 8, 13}) {
        const cv::Mat img = noise(w, h, 50, 0.7, std::uint64_t(w * 100 + h));
        ASSERT_NO_FATAL_FAILURE(expect_same_as_opencv(img, t, std::to_string(w) + "x" + std::to_string(h)));
      }
    }
    ASSERT_NO_FATAL_FAILURE(expect_same_as_opencv(cv::Mat(50, 60, CV_8UC1, cv::Scalar(0)), t, "black"));
    ASSERT_NO_FATAL_FAILURE(expect_same_as_opencv(cv::Mat(50, 60, CV_8UC1, cv::Scalar(255)), t, "white"));
    cv::Mat checker(64, 64, CV_8UC1);
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x) checker.at<std::uint8_t>(y, x) = ((x / 4 + y / 4) % 2) ? 255 : 0;
    ASSERT_NO_FATAL_FAILURE(expect_same_as_opencv(checker, t, "checker"));
  }
}

TEST(FastCorners, SameAsOpenCvOnViews) {
  const cv::Mat scene = cslam::procedural_image(9);
  std::mt19937 rng(5);
  for (int i = 0; i < 40; ++i) {
    const int x = int(rng() % 300), y = int(rng() % 200), w = 7 + int(rng() % 300), h = 7 + int(rng() % 250);
    const cv::Rect r = cv::Rect(x, y, w, h) & cv::Rect(0, 0, scene.cols, scene.rows);
    ASSERT_NO_FATAL_FAILURE(expect_same_as_opencv(scene(r), 7 + int(rng() % 20), "view " + std::to_string(i)));
  }
}

TEST(FastCorners, ScoreIsTheHighestThresholdStillDetected) {
  const cv::Mat img = noise(40, 30, 30, 0.8, 3);
  std::vector<int> detected_at(img.total(), -1);  // highest threshold with the pixel reported
  for (int t = 0; t <= 255; ++t) {
    std::vector<cv::KeyPoint> kps;
    cv::FAST(img, kps, t, false);
    for (const cv::KeyPoint& kp : kps) detected_at[std::size_t(kp.pt.y) * img.cols + std::size_t(kp.pt.x)] = t;
  }
  int corners = 0;
  for (int y = 3; y < img.rows - 3; ++y)
    for (int x = 3; x < img.cols - 3; ++x) {
      const int expected = detected_at[std::size_t(y) * img.cols + std::size_t(x)];
      const int score = cslam::fast_corner_score(img, x, y);
      if (expected >= 0) {
        EXPECT_EQ(score, expected) << x << "," << y;
        ++corners;
      } else {
        EXPECT_LT(score, 0) << x << "," << y;
      }
    }
  EXPECT_GT(corners, 100);
}

TEST(FastCorners, NeighbourScoresAreThePlainScoresOfTheFourNeighbours) {
  // Every pixel at least 4 inside: near the right edge the plain score answers, elsewhere the
  // vector blocks; both must give max(0, fast_corner_score) of each neighbour. Images with dense
  // and sparse corners, and a view into a larger image (its step is not its width).
  const cv::Mat big = noise(120, 60, 40, 0.0, 9);
  const std::vector<cv::Mat> images{noise(64, 40, 30, 0.8, 4), noise(48, 24, 8, 1.5, 5), big(cv::Rect(17, 9, 70, 30)),
                                    cslam::procedural_image(3)(cv::Rect(0, 0, 90, 50))};
  int positive = 0;
  for (const cv::Mat& img : images)
    for (int y = 4; y < img.rows - 4; ++y)
      for (int x = 4; x < img.cols - 4; ++x) {
        const std::array<int, 4> got = cslam::fast_neighbour_scores(img, x, y);
        const int expected[4] = {cslam::fast_corner_score(img, x - 1, y), cslam::fast_corner_score(img, x + 1, y),
                                 cslam::fast_corner_score(img, x, y - 1), cslam::fast_corner_score(img, x, y + 1)};
        for (int k = 0; k < 4; ++k) {
          ASSERT_EQ(got[k], std::max(0, expected[k])) << "neighbour " << k << " of " << x << "," << y;
          positive += got[k] > 0;
        }
      }
  EXPECT_GT(positive, 1000);
  EXPECT_THROW(cslam::fast_neighbour_scores(images[0], 3, 10), std::invalid_argument);
  EXPECT_THROW(cslam::fast_neighbour_scores(images[0], 10, images[0].rows - 4), std::invalid_argument);
}

TEST(FastCorners, DefaultIsTheFastestPath) {
  const cv::Mat scene = cslam::procedural_image(2);
  std::vector<cv::KeyPoint> by_default, fastest;
  cslam::detect_fast_corners(scene, 7, by_default);
  cslam::detect_fast_corners(scene, 7, fastest, cslam::fast_corners_best_path());
  ASSERT_EQ(by_default.size(), fastest.size());
  EXPECT_GT(by_default.size(), 1000u);
#if defined(__x86_64__)
  EXPECT_NE(cslam::fast_corners_best_path(), cslam::FastCornersPath::kScalar);
#endif
}

TEST(FastCorners, RejectsOtherImageTypes) {
  std::vector<cv::KeyPoint> kps;
  EXPECT_THROW(cslam::detect_fast_corners(cv::Mat(20, 20, CV_8UC3), 10, kps), std::invalid_argument);
  EXPECT_THROW(cslam::fast_corner_score(cv::Mat(20, 20, CV_8UC1), 2, 10), std::invalid_argument);
}
