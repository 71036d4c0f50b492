// The codec plugins (codec/codec_plugins.h): OpenCV's image codecs and libavcodec are mapped into
// the process only when first used, and then work as the linked libraries did.
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "codec/codec_plugins.h"
#include "codec/image_codec.h"
#include "codec/png16_fixtures.h"
#include "codec/video_codec.h"

namespace cslam {
namespace {

// Whether a shared object whose file name contains `name` is mapped into this process.
bool mapped(const std::string& name) {
  std::ifstream maps("/proc/self/maps");
  std::string line;
  while (std::getline(maps, line))
    if (line.find(name) != std::string::npos) return true;
  return false;
}

// One test: the order matters (nothing may have loaded a plugin before).
TEST(CodecPlugins, LoadedOnFirstUseOnly) {
  ASSERT_TRUE(mapped("libturbojpeg")) << "the check reads /proc/self/maps";
  EXPECT_FALSE(mapped("libopencv_imgcodecs")) << "a program linking cslam_codec must not map OpenCV's codecs at start";
  EXPECT_FALSE(mapped("libavcodec")) << "nor libavcodec";

  // Wire PNGs of the plain kinds (8-bit RGB, 16-bit grey; built here by hand) decode without
  // OpenCV's codecs: libdeflate inflates them once (codec/png16_decode.h).
  const cv::Mat depth = test::synthetic_depth(32, 24, "smooth", 3);
  const Bytes depth_png = test::hand_png(depth, {4, 1, 0, 2, 3});
  const cv::Mat depth_back = decode_depth(DepthCodec::kPng, depth_png.data(), depth_png.size(), 32, 24, "test");
  EXPECT_EQ(cv::norm(depth_back, depth, cv::NORM_INF), 0.0);
  cv::Mat colour(24, 32, CV_8UC3);
  cv::randu(colour, 0, 255);
  const Bytes colour_png =
      test::build_png(test::ihdr(32, 24, 8, 2), test::zlib_compress(test::filter_rows_rgb8(colour, {1, 4}), 6), 8192);
  const cv::Mat colour_back = decode_rgb(RgbCodec::kPng, colour_png.data(), colour_png.size(), 32, 24, "test");
  EXPECT_EQ(cv::norm(colour_back, colour, cv::NORM_INF), 0.0);
  EXPECT_FALSE(mapped("libopencv_imgcodecs")) << "a plain wire PNG went through OpenCV's decoder";

  // PNG colour goes through OpenCV's encoder (the image I/O plugin) and comes back exactly.
  cv::Mat bgr(24, 32, CV_8UC3);
  cv::randu(bgr, 0, 255);
  CodecOptions png;
  png.rgb = RgbCodec::kPng;
  const Bytes bytes = encode_rgb(bgr, png);
  EXPECT_TRUE(mapped("libcslam_opencv_image_io.so"));
  EXPECT_TRUE(mapped("libopencv_imgcodecs"));
  EXPECT_FALSE(mapped("libavcodec"));
  const cv::Mat back = decode_rgb(RgbCodec::kPng, bytes.data(), bytes.size(), 32, 24, "test");
  EXPECT_EQ(cv::norm(back, bgr, cv::NORM_INF), 0.0);
  const cv::Mat direct = image_io().imdecode(cv::Mat(bytes), cv::IMREAD_COLOR);
  EXPECT_EQ(cv::norm(direct, bgr, cv::NORM_INF), 0.0);

  // The first H.264 encoder loads libavcodec; its packets decode.
  video::H264Encoder encoder(32, 24);
  EXPECT_TRUE(mapped("libcslam_h264.so"));
  EXPECT_TRUE(mapped("libavcodec"));
  video::H264Decoder decoder(32, 24);
  const Bytes packet = encoder.encode(bgr);
  const cv::Mat picture = decoder.decode(packet.data(), packet.size(), "test");
  EXPECT_EQ(picture.size(), bgr.size());
  EXPECT_EQ(decoder.stats().decoded, 1u);
}

}  // namespace
}  // namespace cslam
