#include "codec/depth_subsample.h"

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
  cv::Mat out(height, width, CV_16UC1);
  for (int y = 0; y < height; ++y) {
    const auto* src = coarse.ptr<std::uint16_t>(y / subsample);
    auto* dst = out.ptr<std::uint16_t>(y);
    for (int x = 0; x < width; ++x) dst[x] = src[x / subsample];
  }
  return out;
}

}  // namespace cslam
