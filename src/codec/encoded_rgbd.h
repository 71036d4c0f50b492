#pragma once
// One RGB-D frame's images as a robot sent them (compressed, never re-encoded): kept for the
// keyframes so the dense map can be built, and rebuilt, from exactly what was received.
#include <cstddef>
#include <string>
#include <utility>

#include <opencv2/core.hpp>

#include "codec/image_codec.h"

namespace cslam {

struct EncodedRgbd {
  RgbCodec rgb_codec = RgbCodec::kJpeg;
  std::string rgb;
  DepthCodec depth_codec = DepthCodec::kZstdDelta;
  std::string depth;
  std::size_t bytes() const { return rgb.size() + depth.size(); }
};

// Decodes both images to exactly width x height (BGR8, raw depth16). Throws InputError naming
// `source` on corrupt or truncated bytes.
inline std::pair<cv::Mat, cv::Mat> decode_rgbd(const EncodedRgbd& e, int width, int height, const std::string& source) {
  cv::Mat bgr = decode_rgb(e.rgb_codec, reinterpret_cast<const std::uint8_t*>(e.rgb.data()), e.rgb.size(), width,
                           height, source + " rgb");
  cv::Mat depth = decode_depth(e.depth_codec, reinterpret_cast<const std::uint8_t*>(e.depth.data()), e.depth.size(),
                               width, height, source + " depth");
  return {std::move(bgr), std::move(depth)};
}

}  // namespace cslam
