#pragma once
// Uniform 8-bit noise, the same for a given seed: every rounding case of a filter sooner or later.
#include <opencv2/core.hpp>

namespace cslam {

inline cv::Mat noise_image(cv::Size size, unsigned seed) {
  cv::Mat image(size, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  return image;
}

}  // namespace cslam
