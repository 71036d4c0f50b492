#pragma once
// Colour test images for the codec tests: uniform noise blurred into some structure, like a real
// image's texture (JPEG and H.264 sizes grow with `sigma` falling).
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace cslam::test {

inline cv::Mat blurred_noise_bgr(int w, int h, unsigned seed, double sigma) {
  cv::Mat im(h, w, CV_8UC3);
  cv::RNG rng(seed);
  rng.fill(im, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(im, im, cv::Size(5, 5), sigma);
  return im;
}

}  // namespace cslam::test
