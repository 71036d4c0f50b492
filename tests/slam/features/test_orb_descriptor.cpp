#include <cmath>
#include <set>
#include <tuple>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "slam/features/orb_blur.h"
#include "slam/features/orb_descriptor.h"
#include "slam/features/procedural_image.h"

namespace cslam {
namespace {

// cv::ORB::compute's descriptors of `kps` on `image` (none may be dropped).
std::vector<Descriptor> opencv_descriptors(const cv::Mat& image, std::vector<cv::KeyPoint> kps) {
  for (int i = 0; i < int(kps.size()); ++i) kps[std::size_t(i)].class_id = i;
  const cv::Ptr<cv::ORB> orb = cv::ORB::create(1000, 1.2f, 1, 19, 0, 2, cv::ORB::FAST_SCORE, 31, 20);
  cv::Mat desc;
  const std::size_t n = kps.size();
  orb->compute(image, kps, desc);
  EXPECT_EQ(kps.size(), n);
  std::vector<Descriptor> out(n);
  for (int r = 0; r < desc.rows; ++r) out[std::size_t(kps[std::size_t(r)].class_id)] = descriptor_from_row(desc.row(r));
  return out;
}

std::vector<Descriptor> our_descriptors(const cv::Mat& image, const std::vector<cv::KeyPoint>& kps,
                                        const OrbPattern& pattern) {
  cv::Mat blurred;
  orb_blur(image, blurred);
  std::vector<Descriptor> out;
  compute_orb_descriptors(blurred, kps, pattern, out);
  return out;
}

// An angle at which cos/sin of the float differ from the double ones rounded to float: cv::ORB
// uses the float functions, and a point near a pixel boundary then rounds the other way.
bool float_trig_differs(float degrees) {
  const float a = degrees * float(CV_PI / 180.f);
  return std::cos(a) != float(std::cos(double(a))) || std::sin(a) != float(std::sin(double(a)));
}

// Keypoints at integer positions anywhere a level's keypoints may be (19 pixels from the border),
// a quarter at angles where float and double trigonometry differ, some at the right angles.
std::vector<cv::KeyPoint> keypoints_over(const cv::Mat& image, int count, cv::RNG& rng) {
  std::vector<cv::KeyPoint> kps;
  for (int k = 0; k < count; ++k) {
    float angle = rng.uniform(0.f, 360.f);
    if (k % 4 == 0)
      while (!float_trig_differs(angle)) angle = rng.uniform(0.f, 360.f);
    if (k < 8) angle = 45.f * float(k);
    kps.emplace_back(float(rng.uniform(19, image.cols - 19)), float(rng.uniform(19, image.rows - 19)), 31.f, angle);
  }
  return kps;
}

TEST(OrbDescriptor, ThePatternIsReadFromOpenCv) {
  const std::unique_ptr<OrbPattern> pattern = probe_opencv_orb_pattern();
  ASSERT_NE(pattern, nullptr);
  ASSERT_NE(opencv_orb_pattern(), nullptr);
  std::set<std::tuple<float, float, float, float>> pairs;
  for (int i = 0; i < 256; ++i) {
    const float x1 = pattern->x[2 * i], y1 = pattern->y[2 * i], x2 = pattern->x[2 * i + 1], y2 = pattern->y[2 * i + 1];
    for (const float c : {x1, y1, x2, y2}) {
      EXPECT_EQ(c, std::round(c));
      EXPECT_LE(std::abs(c), 15.f);  // inside the 31-pixel patch
    }
    EXPECT_FALSE(x1 == x2 && y1 == y2) << "pair " << i;
    pairs.emplace(x1, y1, x2, y2);
  }
  EXPECT_EQ(pairs.size(), 256u);
}

TEST(OrbDescriptor, BitsEqualOpenCvOrbOnEveryLevelAndAngle) {
  const OrbPattern* pattern = opencv_orb_pattern();
  ASSERT_NE(pattern, nullptr);
  cv::RNG rng(7);
  int compared = 0;
  for (const std::uint64_t seed : {3u, 11u, 29u}) {
    cv::Mat level = procedural_image(seed);
    for (int l = 0; l < 8; ++l) {  // the extractor's pyramid: each level from the one above
      if (l > 0) {
        cv::Mat smaller;
        cv::resize(level, smaller,
                   cv::Size(int(std::lround(640 / std::pow(1.2, l))), int(std::lround(480 / std::pow(1.2, l)))), 0, 0,
                   cv::INTER_LINEAR);
        level = smaller;
      }
      const std::vector<cv::KeyPoint> kps = keypoints_over(level, 300, rng);
      const std::vector<Descriptor> theirs = opencv_descriptors(level, kps),
                                    ours = our_descriptors(level, kps, *pattern);
      ASSERT_EQ(ours.size(), theirs.size());
      for (std::size_t i = 0; i < kps.size(); ++i)
        ASSERT_EQ(ours[i], theirs[i]) << "seed " << seed << " level " << l << " keypoint at " << kps[i].pt << " angle "
                                      << kps[i].angle;
      compared += int(kps.size());
    }
  }
  EXPECT_EQ(compared, 3 * 8 * 300);
}

TEST(OrbDescriptor, FlatImagesCompareStrictly) {
  // Nearly flat images: most compared values are equal, and "darker" must be strict as OpenCV's.
  const OrbPattern* pattern = opencv_orb_pattern();
  ASSERT_NE(pattern, nullptr);
  cv::RNG rng(8);
  for (const int span : {1, 2, 3}) {
    cv::Mat img(120, 160, CV_8UC1);
    rng.fill(img, cv::RNG::UNIFORM, 100, 100 + span + 1);
    const std::vector<cv::KeyPoint> kps = keypoints_over(img, 200, rng);
    EXPECT_EQ(our_descriptors(img, kps, *pattern), opencv_descriptors(img, kps)) << "span " << span;
  }
}

TEST(OrbDescriptor, AnyChangedPointShowsInTheBits) {
  // The comparison above can fail: moving one point of one pair by one pixel changes that bit on
  // a textured image.
  const OrbPattern* pattern = opencv_orb_pattern();
  ASSERT_NE(pattern, nullptr);
  const cv::Mat img = procedural_image(5);
  cv::RNG rng(9);
  const std::vector<cv::KeyPoint> kps = keypoints_over(img, 300, rng);
  const std::vector<Descriptor> theirs = opencv_descriptors(img, kps);
  for (const int point : {0, 77, 311, 511}) {
    OrbPattern moved = *pattern;
    moved.x[std::size_t(point)] += 1.f;
    const std::vector<Descriptor> ours = our_descriptors(img, kps, moved);
    int differing = 0;
    for (std::size_t i = 0; i < kps.size(); ++i) differing += ours[i] != theirs[i];
    EXPECT_GT(differing, 10) << "point " << point;
  }
}

}  // namespace
}  // namespace cslam
