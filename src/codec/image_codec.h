#pragma once
// Image codecs for sending RGB-D frames over the network (no network code here).
// RGB: raw BGR8 / JPEG (quality option) / PNG / standalone H.264 pictures. Depth (16-bit): raw /
// PNG / RVL / zstd of a delta-coded image. Every depth codec is lossless. Decoders check
// everything they read and throw InputError naming the source on bad bytes; they never trust
// sizes found in the data.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace cslam {

// kH264Intra: one H.264 key picture per image (ImageEncoder, video::intra_image()): it decodes on
// its own, so keyframes can be stored as sent; smaller than JPEG q75 at equal quality.
enum class RgbCodec { kRaw, kJpeg, kPng, kH264Intra };
enum class DepthCodec { kRaw, kPng, kRvl, kZstdDelta };

struct CodecOptions {
  RgbCodec rgb = RgbCodec::kJpeg;
  DepthCodec depth = DepthCodec::kZstdDelta;
  // Default pair JPEG q75 + zstd: 94.3 KB/frame on tum_fr1_rpy (q80: 99.9, q90: 125.9), see docs/network.md.
  int jpeg_quality = 75;    // 1..100
  int png_compression = 1;  // 0..9 (OpenCV/zlib level); 1 is fast and close to the best size
  int h264_intra_crf = 15;  // 0..51: kH264Intra's x264 constant rate factor (video::intra_image)
  int zstd_level = 1;       // zstd level for kZstdDelta
  // Throws ConfigError on an out-of-range value.
  void validate() const;
};

const char* to_string(RgbCodec codec);
const char* to_string(DepthCodec codec);
// A stream's full frames' colour codec unless one is chosen ("auto" in the programs): in a stream
// with light frames (a lean or adaptive one), standalone H.264 pictures, smaller than JPEG q75
// with more ORB features kept (the lean stream's ATE over 24 demo scenes: 1.085x the default
// pair's with these; the full frames' colour sets it, docs/results/bandwidth.md, and a byte budget
// makes it finer where the robot's link share has room, codec/byte_budget.h); JPEG when every
// frame is full (a picture costs the server 4x a JPEG's decoding, and the robot 4x its encoding).
RgbCodec auto_rgb_codec(bool light_frames);
// "raw" | "jpeg" | "png" | "h264-intra"; throws ConfigError otherwise. "jpeg90" sets quality too (see parse_codecs).
RgbCodec parse_rgb_codec(const std::string& name);
// As parse_rgb_codec, and "auto": auto_rgb_codec(light_frames) (the programs' --rgb-codec).
RgbCodec parse_rgb_codec(const std::string& name, bool light_frames);
// "raw" | "png" | "rvl" | "zstd"; throws ConfigError otherwise.
DepthCodec parse_depth_codec(const std::string& name);

using Bytes = std::vector<std::uint8_t>;

// bgr: CV_8UC3. Throws std::invalid_argument on a wrong image type, and for kH264Intra, whose
// pictures come from a stream's ImageEncoder (codec/image_encoder.h).
Bytes encode_rgb(const cv::Mat& bgr, const CodecOptions& options);
// depth: CV_16UC1. Throws std::invalid_argument on a wrong image type.
Bytes encode_depth(const cv::Mat& depth, const CodecOptions& options);

// Decodes into an image of exactly width x height (CV_8UC3 / CV_16UC1). Throws InputError(source, ...)
// if the bytes are corrupt, truncated or of another size than announced.
cv::Mat decode_rgb(RgbCodec codec, const std::uint8_t* data, std::size_t size, int width, int height,
                   const std::string& source);
cv::Mat decode_depth(DepthCodec codec, const std::uint8_t* data, std::size_t size, int width, int height,
                     const std::string& source);

// Largest image side a decoder accepts (guards against absurd sizes in headers and messages).
constexpr int kMaxImageSide = 8192;

}  // namespace cslam
