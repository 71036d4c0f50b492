#include "codec/depth_subsample.h"

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace cslam {

namespace {

void check_subsample(int subsample) {
  if (subsample < 1 || subsample > kMaxDepthSubsample)
    throw std::invalid_argument("depth subsample " + std::to_string(subsample) + " is not 1.." +
                                std::to_string(kMaxDepthSubsample));
}

}  // namespace

cv::Size subsampled_depth_size(int width, int height, int subsample) {
  check_subsample(subsample);
  return {(width + subsample - 1) / subsample, (height + subsample - 1) / subsample};
}

cv::Mat subsample_depth(const cv::Mat& depth, int subsample) {
  if (depth.type() != CV_16UC1) throw std::invalid_argument("subsample_depth: depth must be CV_16UC1");
  const cv::Size size = subsampled_depth_size(depth.cols, depth.rows, subsample);
  cv::Mat out(size, CV_16UC1);
  for (int y = 0; y < size.height; ++y) {
    const auto* src = depth.ptr<std::uint16_t>(y * subsample);
    auto* dst = out.ptr<std::uint16_t>(y);
    for (int x = 0; x < size.width; ++x) dst[x] = src[x * subsample];
  }
  return out;
}

cv::Mat expand_depth(const cv::Mat& coarse, int subsample, int width, int height) {
  if (coarse.type() != CV_16UC1 || coarse.size() != subsampled_depth_size(width, height, subsample))
    throw std::invalid_argument("expand_depth: the coarse image is not the subsampled size of " +
                                std::to_string(width) + "x" + std::to_string(height));
  // Each coarse row is spread once into the first full row of its block, which the block's other
  // rows copy: no division per pixel (this runs on every light frame before its tracking).
  cv::Mat out(height, width, CV_16UC1);
  for (int y0 = 0; y0 < height; y0 += subsample) {
    const auto* src = coarse.ptr<std::uint16_t>(y0 / subsample);
    auto* first = out.ptr<std::uint16_t>(y0);
    for (int x0 = 0, i = 0; x0 < width; x0 += subsample, ++i)
      std::fill(first + x0, first + std::min(x0 + subsample, width), src[i]);
    for (int y = y0 + 1; y < std::min(y0 + subsample, height); ++y)
      std::copy(first, first + width, out.ptr<std::uint16_t>(y));
  }
  return out;
}

}  // namespace cslam
