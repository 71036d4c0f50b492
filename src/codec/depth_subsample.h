#pragma once
// Depth at a fraction of the pixels, for a lean stream's light frames (docs/network.md): the
// robot keeps every S-th pixel of every S-th row (no averaging, so no depth is invented across
// an edge) and sends that small image losslessly; the server spreads each sample over its S x S
// block to get back a full-size image that tracking reads keypoint depths from. Such a frame
// never becomes a keyframe (the map and the dense model need every pixel).
#include <opencv2/core.hpp>

namespace cslam {

constexpr int kMaxDepthSubsample = 16;

// Size of the subsampled image of a width x height depth image: ceil(width/S) x ceil(height/S).
cv::Size subsampled_depth_size(int width, int height, int subsample);
// depth: CV_16UC1; subsample 1..kMaxDepthSubsample (else std::invalid_argument).
cv::Mat subsample_depth(const cv::Mat& depth, int subsample);
// The full-size image (width x height) with every pixel taken from the sample of its block.
// coarse must be exactly subsampled_depth_size(width, height, subsample), else std::invalid_argument.
cv::Mat expand_depth(const cv::Mat& coarse, int subsample, int width, int height);

}  // namespace cslam
