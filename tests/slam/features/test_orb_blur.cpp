// orb_blur against cv::ORB's own blur (cv::GaussianBlur on a submatrix of a bordered copy): the
// same pixels by both paths, for the ORB pyramid's sizes, odd and tiny sizes, views into larger
// images, noise and real-looking scenes.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "core/cpu_features.h"
#include "slam/features/orb_blur.h"
#include "slam/features/procedural_image.h"
#include "slam/features/noise_image.h"

namespace cslam {
namespace {

// As cv::ORB blurs a level: a copy bordered by its edge threshold (19), the inner part blurred in
// place (what OrbExtractor ran before orb_blur).
cv::Mat as_cv_orb_blurs(const cv::Mat& level) {
  cv::Mat bordered;
  cv::copyMakeBorder(level, bordered, 19, 19, 19, 19, cv::BORDER_REFLECT_101 + cv::BORDER_ISOLATED);
  cv::Mat inner = bordered(cv::Rect(19, 19, level.cols, level.rows));
  cv::GaussianBlur(inner, inner, cv::Size(7, 7), 2, 2, cv::BORDER_REFLECT_101);
  return inner.clone();
}

int differing_pixels(const cv::Mat& image, OrbBlurPath path) {
  cv::Mat actual;
  orb_blur(image, actual, path);
  const cv::Mat expected = as_cv_orb_blurs(image);
  if (actual.size() != image.size() || actual.type() != CV_8UC1) return -1;
  return cv::countNonZero(actual != expected);
}

std::vector<OrbBlurPath> paths() {
  std::vector<OrbBlurPath> out{OrbBlurPath::kOpenCv};
  if (cpu_has_avx2_fma()) out.push_back(OrbBlurPath::kAvx2Fma);
  return out;
}

TEST(OrbBlur, TheVectorPathIsChosenWhereTheCpuHasAvx2AndFma) {
  // The fast path reproduces Debian 12's OpenCV on such a CPU; losing it would cost every frame.
  const OrbBlurPath expected = cpu_has_avx2_fma() ? OrbBlurPath::kAvx2Fma : OrbBlurPath::kOpenCv;
  EXPECT_EQ(orb_blur_best_path(), expected);
}

TEST(OrbBlur, OrbPyramidOfNoiseAndScenes) {
  for (const cv::Size base : {cv::Size(640, 480), cv::Size(752, 480), cv::Size(1241, 376)}) {
    ProceduralImageConfig scene;
    scene.width = base.width;
    scene.height = base.height;
    for (const cv::Mat& image : {noise_image(base, 3), procedural_image(7, scene)})
      for (int l = 0; l < 8; ++l) {
        const cv::Size size(int(std::lround(base.width / std::pow(1.2, l))),
                            int(std::lround(base.height / std::pow(1.2, l))));
        cv::Mat level;
        cv::resize(image, level, size, 0, 0, cv::INTER_LINEAR);
        for (const OrbBlurPath path : paths())
          EXPECT_EQ(differing_pixels(level, path), 0) << size << " path " << int(path);
      }
  }
}

TEST(OrbBlur, OddAndTinySizesAndViews) {
  const cv::Mat big = noise_image(cv::Size(300, 200), 5);
  for (const cv::Size size : {cv::Size(4, 4), cv::Size(5, 9), cv::Size(15, 4), cv::Size(17, 33), cv::Size(46, 46),
                              cv::Size(63, 47), cv::Size(129, 7)})
    for (const OrbBlurPath path : paths()) {
      EXPECT_EQ(differing_pixels(noise_image(size, unsigned(size.area())), path), 0) << size << " path " << int(path);
      // A view into a larger image: only its own pixels count, the reflected border is its own.
      EXPECT_EQ(differing_pixels(big(cv::Rect(cv::Point(31, 17), size)), path), 0) << "view " << size;
    }
}

TEST(OrbBlur, HardEdgesAndSaturation) {
  cv::Mat edges(97, 131, CV_8UC1);
  for (int y = 0; y < edges.rows; ++y)
    for (int x = 0; x < edges.cols; ++x) edges.at<std::uint8_t>(y, x) = ((x / 3 + y / 2) % 2) ? 255 : 0;
  const cv::Mat white(40, 40, CV_8UC1, cv::Scalar(255)), black(40, 40, CV_8UC1, cv::Scalar(0));
  for (const OrbBlurPath path : paths())
    for (const cv::Mat& image : {edges, white, black}) EXPECT_EQ(differing_pixels(image, path), 0);
  cv::Mat out;
  orb_blur(white, out);
  EXPECT_EQ(cv::countNonZero(out != 255), 0);  // a flat image stays flat: no rounding drift
}

TEST(OrbBlur, RejectsOtherTypesAndTooSmallImages) {
  cv::Mat out;
  for (const OrbBlurPath path : paths()) {
    EXPECT_THROW(orb_blur(cv::Mat(40, 40, CV_8UC3), out, path), std::invalid_argument);
    EXPECT_THROW(orb_blur(cv::Mat(40, 40, CV_16UC1), out, path), std::invalid_argument);
    EXPECT_THROW(orb_blur(cv::Mat(3, 40, CV_8UC1), out, path), std::invalid_argument);
    EXPECT_THROW(orb_blur(cv::Mat(40, 3, CV_8UC1), out, path), std::invalid_argument);
  }
  if (!cpu_has_avx2_fma()) {  // the vector path is refused where the CPU cannot run it
    EXPECT_THROW(orb_blur(cv::Mat(40, 40, CV_8UC1), out, OrbBlurPath::kAvx2Fma), std::invalid_argument);
  }
}

}  // namespace
}  // namespace cslam
