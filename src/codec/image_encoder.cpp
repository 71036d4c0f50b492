#include "codec/image_encoder.h"

#include <stdexcept>

#include "codec/video_codec.h"

namespace cslam {

ImageEncoder::ImageEncoder(const CodecOptions& options, cv::Size size) : options_(options) {
  options_.validate();
  if (options_.rgb == RgbCodec::kH264Intra && !size.empty())
    intra_ = std::make_unique<video::H264Encoder>(size.width, size.height, video::intra_image(options_.h264_intra_crf));
}

ImageEncoder::~ImageEncoder() = default;
ImageEncoder::ImageEncoder(ImageEncoder&&) noexcept = default;
ImageEncoder& ImageEncoder::operator=(ImageEncoder&&) noexcept = default;

Bytes ImageEncoder::rgb(const cv::Mat& bgr) {
  if (options_.rgb != RgbCodec::kH264Intra) return encode_rgb(bgr, options_);
  if (bgr.type() != CV_8UC3 || bgr.empty()) throw std::invalid_argument("ImageEncoder: expected a CV_8UC3 image");
  if (!intra_)
    intra_ = std::make_unique<video::H264Encoder>(bgr.cols, bgr.rows, video::intra_image(options_.h264_intra_crf));
  return intra_->encode(bgr);
}

EncodedRgb ImageEncoder::rgb_within(const cv::Mat& bgr, std::size_t allowance, const std::vector<int>& jpeg_qualities) {
  const bool lossless = options_.rgb == RgbCodec::kRaw || options_.rgb == RgbCodec::kPng;
  if (!lossless && allowance > 0) {
    CodecOptions jpeg = options_;
    jpeg.rgb = RgbCodec::kJpeg;
    for (int quality : jpeg_qualities) {
      if (options_.rgb == RgbCodec::kJpeg && quality <= options_.jpeg_quality) break;
      // A quality whose last picture was far over is not tried: a robot's pictures change
      // little from one full frame to the next, and each trial costs a JPEG encoding.
      const auto last = jpeg_sizes_.find(quality);
      if (last != jpeg_sizes_.end() && double(last->second) > kSkipFactor * double(allowance)) continue;
      jpeg.jpeg_quality = quality;
      Bytes bytes = encode_rgb(bgr, jpeg);
      jpeg_sizes_[quality] = bytes.size();
      if (bytes.size() <= allowance) return {RgbCodec::kJpeg, std::move(bytes), quality, true};
    }
  }
  return {options_.rgb, rgb(bgr), options_.rgb == RgbCodec::kJpeg ? options_.jpeg_quality : 0, false};
}

EncodedRgb ImageEncoder::full_colour(const cv::Mat& bgr, const ByteBudget* budget, std::size_t other_image_bytes) {
  if (!budget || !budget->enabled()) return rgb_within(bgr, 0, {});  // no room: the options' own codec
  return rgb_within(bgr, budget->image_allowance(other_image_bytes), budget->config().jpeg_qualities);
}

}  // namespace cslam
