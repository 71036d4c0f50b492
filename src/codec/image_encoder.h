#pragma once
// One stream's encoder for images that must decode on their own (a full frame's colour and
// depth, which may become a keyframe). Raw, JPEG, PNG and every depth codec are stateless
// (encode_rgb / encode_depth). RgbCodec::kH264Intra keeps one H.264 encoder for the stream
// (video::intra_image(): key interval 1, so every picture is a key packet that decodes alone):
// x264's rate control learns from the pictures before, and a fresh encoder per picture codes
// each one as a stream's first (on fr1/desk at CRF 15: 84 KB at 41 dB and 9 ms instead of 30 KB
// at 38 dB and 4.5 ms). So a picture's bytes depend on the pictures encoded before it by this
// object; a client that sends them in order (C++ or Python) sends the same bytes.
#include <cstddef>
#include <map>
#include <memory>
#include <vector>

#include <opencv2/core.hpp>

#include "codec/byte_budget.h"
#include "codec/image_codec.h"

namespace cslam {

namespace video {
class H264Encoder;
}

struct EncodedRgb {
  RgbCodec codec = RgbCodec::kRaw;
  Bytes bytes;
  int jpeg_quality = 0;  // with kJpeg: the quality used
  bool finer = false;    // rgb_within chose a JPEG finer than the options' own codec
};

class ImageEncoder {
 public:
  // Throws ConfigError on invalid options (CodecOptions::validate). With a size (the camera's),
  // kH264Intra's encoder is made at once, so odd or out-of-range sides fail here (ConfigError);
  // without one, at the first picture.
  explicit ImageEncoder(const CodecOptions& options, cv::Size size = {});
  ~ImageEncoder();
  ImageEncoder(ImageEncoder&&) noexcept;
  ImageEncoder& operator=(ImageEncoder&&) noexcept;

  // bgr: CV_8UC3, else std::invalid_argument; with kH264Intra of the first picture's size (even
  // sides) on every call, else std::invalid_argument (ConfigError for odd sides).
  Bytes rgb(const cv::Mat& bgr);
  // A full frame's colour within a byte budget (codec/byte_budget.h): the first of
  // `jpeg_qualities` (finest first) finer than the options' own JPEG quality whose picture takes
  // at most `allowance` bytes, else rgb() with the options' codec. Lossless codecs (raw, PNG) are
  // never replaced. A quality whose picture was over kSkipFactor x the allowance the last time
  // it was tried is skipped (one JPEG encoding per full frame instead of up to three). Same
  // argument checks as rgb().
  EncodedRgb rgb_within(const cv::Mat& bgr, std::size_t allowance, const std::vector<int>& jpeg_qualities);
  // A full frame's colour: rgb_within the room an enabled `budget` leaves beside the frame's
  // `other_image_bytes` (its depth), else rgb() with the options' codec. The sender's wire frames
  // and the offline simulation both take their colour from here.
  EncodedRgb full_colour(const cv::Mat& bgr, const ByteBudget* budget, std::size_t other_image_bytes);
  // depth: CV_16UC1, else std::invalid_argument.
  Bytes depth(const cv::Mat& depth) const { return encode_depth(depth, options_); }
  const CodecOptions& options() const { return options_; }

 private:
  CodecOptions options_;
  std::unique_ptr<video::H264Encoder> intra_;  // kH264Intra: made at the first picture
  std::map<int, std::size_t> jpeg_sizes_;      // rgb_within: JPEG quality -> its last picture's bytes
  static constexpr double kSkipFactor = 1.25;
};

}  // namespace cslam
