// Round trips, losslessness and bad input for every image codec.
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "codec/depth_subsample.h"
#include "codec/image_codec.h"
#include "codec/image_encoder.h"
#include "codec/video_codec.h"
#include "common/test_images.h"
#include "core/error.h"

namespace cslam {
namespace {

cv::Mat random_bgr(int w, int h, unsigned seed) { return test::blurred_noise_bgr(w, h, seed, 1.5); }

// Smooth depth ramps with holes (0) and a few far outliers: what Kinect depth looks like.
cv::Mat random_depth(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> noise(-3, 3), hole(0, 19);
  cv::Mat d(h, w, CV_16UC1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      int v = 4000 + 20 * x + 7 * y + noise(rng);
      if (hole(rng) == 0) v = 0;
      if (x == w / 2 && y == h / 2) v = 65535;
      d.at<std::uint16_t>(y, x) = std::uint16_t(v);
    }
  return d;
}

struct RgbCase {
  RgbCodec codec;
  double max_mean_error;  // 0: lossless
};
class RgbCodecTest : public ::testing::TestWithParam<RgbCase> {};

TEST_P(RgbCodecTest, RoundTripKeepsSizeAndContent) {
  const cv::Mat im = random_bgr(64, 48, 1);
  CodecOptions o;
  o.rgb = GetParam().codec;
  o.jpeg_quality = 95;
  o.h264_intra_crf = 8;  // both lossy codecs at a high quality
  const Bytes bytes = ImageEncoder(o).rgb(im);
  const cv::Mat back = decode_rgb(o.rgb, bytes.data(), bytes.size(), 64, 48, "test");
  ASSERT_EQ(back.type(), CV_8UC3);
  ASSERT_EQ(back.cols, 64);
  ASSERT_EQ(back.rows, 48);
  if (GetParam().max_mean_error == 0) {
    EXPECT_EQ(cv::norm(im, back, cv::NORM_INF), 0.0);
  } else {
    EXPECT_LT(cv::norm(im, back, cv::NORM_L1) / double(im.total() * 3), GetParam().max_mean_error);
  }
}

TEST_P(RgbCodecTest, WrongAnnouncedSizeIsRejected) {
  const cv::Mat im = random_bgr(64, 48, 2);
  CodecOptions o;
  o.rgb = GetParam().codec;
  const Bytes bytes = ImageEncoder(o).rgb(im);
  EXPECT_THROW(decode_rgb(o.rgb, bytes.data(), bytes.size(), 32, 48, "test"), InputError);
  EXPECT_THROW(decode_rgb(o.rgb, bytes.data(), bytes.size(), 64, 0, "test"), InputError);
}

TEST_P(RgbCodecTest, TruncatedOrGarbageIsRejectedOrDecodesToTheRightSize) {
  const cv::Mat im = random_bgr(64, 48, 3);
  CodecOptions o;
  o.rgb = GetParam().codec;
  const Bytes bytes = ImageEncoder(o).rgb(im);
  for (std::size_t keep : {std::size_t(0), std::size_t(3), bytes.size() / 4, bytes.size() / 2}) {
    try {
      const cv::Mat back = decode_rgb(o.rgb, bytes.data(), keep, 64, 48, "test");
      // libjpeg fills a truncated scan with grey; the size must still be right.
      EXPECT_EQ(back.cols, 64);
      EXPECT_EQ(back.rows, 48);
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("test"), std::string::npos);
    }
  }
  const Bytes garbage(500, 0xab);
  EXPECT_THROW(decode_rgb(o.rgb, garbage.data(), garbage.size(), 64, 48, "test"), InputError);
}

// The network decoder's JPEG path (header checks, then codec/jpeg_decode.h): the same pixels as
// cv::imdecode, and a truncated stream is refused rather than filled with grey.
TEST(RgbJpeg, DecodesLikeOpenCvAndRefusesTruncation) {
  const cv::Mat im = random_bgr(160, 120, 4);
  CodecOptions o;
  o.rgb = RgbCodec::kJpeg;
  const Bytes bytes = ImageEncoder(o).rgb(im);
  const cv::Mat expected = cv::imdecode(bytes, cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
  const cv::Mat back = decode_rgb(o.rgb, bytes.data(), bytes.size(), 160, 120, "test");
  EXPECT_EQ(cv::norm(back, expected, cv::NORM_INF), 0.0);
  for (std::size_t keep = 0; keep < bytes.size(); keep += 41)
    EXPECT_THROW(decode_rgb(o.rgb, bytes.data(), keep, 160, 120, "test"), InputError) << keep;
  EXPECT_THROW(decode_rgb(o.rgb, bytes.data(), bytes.size() - 1, 160, 120, "test"), InputError);
}

// The network decoder's PNG path: plain 8-bit RGB and 16-bit grey PNGs are inflated once by
// libdeflate (codec/png16_decode.h); every other kind a robot may send (here 8-bit grey and 16-bit
// colour written by OpenCV, sent as colour) goes through the stream pre-check and OpenCV, as
// before, and decodes as cv::imdecode does.
TEST(RgbPng, KindsTheFastDecoderLeavesAloneDecodeAsOpenCvDoes) {
  const cv::Mat bgr = random_bgr(40, 30, 9);
  cv::Mat grey, colour16;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  bgr.convertTo(colour16, CV_16UC3, 257.0);
  for (const cv::Mat& im : {bgr, grey, colour16}) {
    Bytes png;
    ASSERT_TRUE(cv::imencode(".png", im, png));
    const cv::Mat expected = cv::imdecode(png, cv::IMREAD_COLOR);
    const cv::Mat back = decode_rgb(RgbCodec::kPng, png.data(), png.size(), 40, 30, "test");
    ASSERT_EQ(back.type(), CV_8UC3) << im.type();
    EXPECT_EQ(cv::norm(back, expected, cv::NORM_INF), 0.0) << im.type();
  }
}

// H.264 codes chroma at half resolution (I420), which blurred noise pays for: mean error ~5 of 255
// even at CRF 8 (a wrong picture: ~60).
INSTANTIATE_TEST_SUITE_P(AllRgb, RgbCodecTest,
                         ::testing::Values(RgbCase{RgbCodec::kRaw, 0}, RgbCase{RgbCodec::kJpeg, 4.0},
                                           RgbCase{RgbCodec::kPng, 0}, RgbCase{RgbCodec::kH264Intra, 8.0}),
                         [](const auto& info) {
                           std::string name = to_string(info.param.codec);
                           for (char& c : name)
                             if (c == '-') c = '_';
                           return name;
                         });

// Every H.264 picture of a stream's ImageEncoder decodes on its own, in any order (what the
// keyframe store relies on), and the same pictures in the same order give the same bytes (what
// the Python client's byte-identity relies on).
TEST(RgbH264Intra, EachPictureStandsAloneAndStreamPacketsAreRefused) {
  const cv::Mat a = random_bgr(64, 48, 5), b = random_bgr(64, 48, 6);
  CodecOptions o;
  o.rgb = RgbCodec::kH264Intra;
  EXPECT_THROW(encode_rgb(a, o), std::invalid_argument);  // stateful: only through an ImageEncoder
  ImageEncoder first(o), second(o);
  const Bytes a1 = first.rgb(a), b1 = first.rgb(b);
  EXPECT_EQ(second.rgb(a), a1);
  EXPECT_EQ(second.rgb(b), b1);
  EXPECT_NE(a1, b1);
  EXPECT_TRUE(video::is_h264_key_packet(a1.data(), a1.size()));
  EXPECT_TRUE(video::is_h264_key_packet(b1.data(), b1.size()));
  const cv::Mat back_b = decode_rgb(o.rgb, b1.data(), b1.size(), 64, 48, "test");
  const cv::Mat back_a = decode_rgb(o.rgb, a1.data(), a1.size(), 64, 48, "test");
  // Blurred noise at the default CRF: mean error ~5 of 255 (a wrong picture: ~60).
  EXPECT_LT(cv::norm(a, back_a, cv::NORM_L1) / double(a.total() * 3), 8.0);
  EXPECT_LT(cv::norm(b, back_b, cv::NORM_L1) / double(b.total() * 3), 8.0);
  // A lower CRF is better and larger.
  CodecOptions fine = o;
  fine.h264_intra_crf = 5;
  EXPECT_GT(ImageEncoder(fine).rgb(a).size(), a1.size());
  EXPECT_THROW(first.rgb(random_bgr(32, 48, 7)), std::invalid_argument);  // the stream's size only
  EXPECT_THROW(ImageEncoder(o, cv::Size(63, 48)), ConfigError);           // a camera H.264 cannot code, at once
  EXPECT_NO_THROW(ImageEncoder(o, cv::Size(64, 48)));
  // An inter-coded packet of a stream is not a standalone picture.
  video::H264Encoder stream(64, 48);
  stream.encode(a);
  const Bytes inter = stream.encode(b);
  ASSERT_FALSE(video::is_h264_key_packet(inter.data(), inter.size()));
  EXPECT_THROW(decode_rgb(o.rgb, inter.data(), inter.size(), 64, 48, "test"), InputError);
  // Any flipped byte is caught (header checks or the CRC).
  for (std::size_t i = 0; i < a1.size(); i += 7) {
    Bytes bad = a1;
    bad[i] ^= 0x10;
    EXPECT_THROW(decode_rgb(o.rgb, bad.data(), bad.size(), 64, 48, "test"), InputError) << i;
  }
  EXPECT_THROW(decode_rgb(o.rgb, a1.data(), a1.size(), 63, 48, "test"), InputError);
}

class DepthCodecTest : public ::testing::TestWithParam<DepthCodec> {};

TEST_P(DepthCodecTest, IsLossless) {
  for (unsigned seed : {1u, 2u, 3u}) {
    const cv::Mat d = random_depth(64 + int(seed), 48, seed);
    CodecOptions o;
    o.depth = GetParam();
    const Bytes bytes = encode_depth(d, o);
    const cv::Mat back = decode_depth(o.depth, bytes.data(), bytes.size(), d.cols, d.rows, "test");
    ASSERT_EQ(back.type(), CV_16UC1);
    EXPECT_EQ(cv::norm(d, back, cv::NORM_INF), 0.0) << "seed " << seed;
  }
}

TEST_P(DepthCodecTest, EdgeCasesAllZeroAllMaxAndOnePixel) {
  CodecOptions o;
  o.depth = GetParam();
  for (const cv::Mat& d : {cv::Mat(cv::Mat::zeros(48, 64, CV_16UC1)), cv::Mat(48, 64, CV_16UC1, cv::Scalar(65535)),
                           cv::Mat(1, 1, CV_16UC1, cv::Scalar(1234))}) {
    const Bytes bytes = encode_depth(d, o);
    const cv::Mat back = decode_depth(o.depth, bytes.data(), bytes.size(), d.cols, d.rows, "test");
    EXPECT_EQ(cv::norm(d, back, cv::NORM_INF), 0.0);
  }
}

TEST(DepthCodecs, CompressedCodecsShrinkSmoothDepth) {
  const cv::Mat d = random_depth(160, 120, 4);
  for (DepthCodec c : {DepthCodec::kPng, DepthCodec::kRvl, DepthCodec::kZstdDelta}) {
    CodecOptions o;
    o.depth = c;
    EXPECT_LT(encode_depth(d, o).size(), d.total() * 2 * 3 / 4) << to_string(c);
  }
}

TEST_P(DepthCodecTest, TruncatedDataIsRejected) {
  const cv::Mat d = random_depth(64, 48, 5);
  CodecOptions o;
  o.depth = GetParam();
  const Bytes bytes = encode_depth(d, o);
  EXPECT_THROW(decode_depth(o.depth, bytes.data(), bytes.size() / 2, 64, 48, "test"), InputError);
  EXPECT_THROW(decode_depth(o.depth, bytes.data(), 0, 64, 48, "test"), InputError);
  EXPECT_THROW(decode_depth(o.depth, bytes.data(), bytes.size(), 64, 47, "test"), InputError);
}

INSTANTIATE_TEST_SUITE_P(AllDepth, DepthCodecTest,
                         ::testing::Values(DepthCodec::kRaw, DepthCodec::kPng, DepthCodec::kRvl,
                                           DepthCodec::kZstdDelta),
                         [](const auto& info) { return std::string(to_string(info.param)); });

TEST(CodecNames, ParseAndPrintRoundTrip) {
  for (auto c : {RgbCodec::kRaw, RgbCodec::kJpeg, RgbCodec::kPng, RgbCodec::kH264Intra})
    EXPECT_EQ(parse_rgb_codec(to_string(c)), c);
  for (auto c : {DepthCodec::kRaw, DepthCodec::kPng, DepthCodec::kRvl, DepthCodec::kZstdDelta})
    EXPECT_EQ(parse_depth_codec(to_string(c)), c);
  EXPECT_THROW(parse_rgb_codec("webp"), ConfigError);
  EXPECT_THROW(parse_depth_codec("jpeg"), ConfigError);
}

TEST(CodecOptions, RejectsOutOfRangeValues) {
  CodecOptions o;
  EXPECT_NO_THROW(o.validate());
  o.jpeg_quality = 0;
  EXPECT_THROW(o.validate(), ConfigError);
  o = CodecOptions();
  o.zstd_level = 40;
  EXPECT_THROW(o.validate(), ConfigError);
  o = CodecOptions();
  o.h264_intra_crf = 52;
  EXPECT_THROW(o.validate(), ConfigError);
}

TEST(CodecDefaults, DepthIsLosslessByDefault) {
  const CodecOptions o;
  EXPECT_NE(o.depth, DepthCodec::kRaw);  // compressed...
  const cv::Mat d = random_depth(64, 48, 9);
  const Bytes bytes = encode_depth(d, o);
  EXPECT_EQ(cv::norm(d, decode_depth(o.depth, bytes.data(), bytes.size(), 64, 48, "t"), cv::NORM_INF),
            0.0);  // ...and lossless
}

TEST(EncodeRejectsWrongTypes, ThrowsInvalidArgument) {
  const CodecOptions o;
  EXPECT_THROW(encode_rgb(cv::Mat(4, 4, CV_8UC1), o), std::invalid_argument);
  EXPECT_THROW(encode_depth(cv::Mat(4, 4, CV_8UC3), o), std::invalid_argument);
  EXPECT_THROW(encode_depth(cv::Mat(), o), std::invalid_argument);
}

}  // namespace
}  // namespace cslam

namespace cslam {

// Light frames' depth: every S-th pixel of every S-th row, and back, each sample over its block.
TEST(DepthSubsample, KeepsEverySthPixelAndSpreadsItOverItsBlock) {
  cv::Mat depth(7, 10, CV_16UC1);
  for (int y = 0; y < depth.rows; ++y)
    for (int x = 0; x < depth.cols; ++x) depth.at<std::uint16_t>(y, x) = std::uint16_t(100 * y + x);
  const cv::Mat coarse = subsample_depth(depth, 4);
  ASSERT_EQ(coarse.size(), cv::Size(3, 2));  // ceil(10/4) x ceil(7/4)
  EXPECT_EQ(subsampled_depth_size(10, 7, 4), cv::Size(3, 2));
  EXPECT_EQ(coarse.at<std::uint16_t>(1, 2), 408);  // row 4, column 8
  const cv::Mat back = expand_depth(coarse, 4, 10, 7);
  ASSERT_EQ(back.size(), depth.size());
  for (int y = 0; y < depth.rows; ++y)
    for (int x = 0; x < depth.cols; ++x)
      EXPECT_EQ(back.at<std::uint16_t>(y, x), depth.at<std::uint16_t>(y / 4 * 4, x / 4 * 4)) << x << "," << y;
  EXPECT_EQ(cv::norm(expand_depth(subsample_depth(depth, 1), 1, 10, 7), depth, cv::NORM_INF), 0.0);  // 1: as is
  EXPECT_THROW(subsample_depth(depth, 0), std::invalid_argument);
  EXPECT_THROW(subsample_depth(depth, kMaxDepthSubsample + 1), std::invalid_argument);
  EXPECT_THROW(expand_depth(coarse, 4, 13, 7), std::invalid_argument);  // 13 wide subsamples to 4 columns, not 3
  cv::Mat wrong_type;
  depth.convertTo(wrong_type, CV_32F);
  EXPECT_THROW(subsample_depth(wrong_type, 2), std::invalid_argument);
}

// Every subsample and sizes that do and do not divide by it: each pixel takes its block's sample.
TEST(DepthSubsample, ExpandsEverySubsampleAndPartialBlock) {
  for (const cv::Size size : {cv::Size(640, 480), cv::Size(33, 17), cv::Size(48, 49)}) {
    cv::Mat depth(size, CV_16UC1);
    for (int y = 0; y < depth.rows; ++y)
      for (int x = 0; x < depth.cols; ++x) depth.at<std::uint16_t>(y, x) = std::uint16_t(1000 * (y % 60) + x);
    for (int s = 1; s <= kMaxDepthSubsample; ++s) {
      const cv::Mat back = expand_depth(subsample_depth(depth, s), s, size.width, size.height);
      ASSERT_EQ(back.size(), size);
      int wrong = 0;
      for (int y = 0; y < depth.rows; ++y)
        for (int x = 0; x < depth.cols; ++x)
          wrong += back.at<std::uint16_t>(y, x) != depth.at<std::uint16_t>(y / s * s, x / s * s);
      EXPECT_EQ(wrong, 0) << size << " S=" << s;
    }
  }
}

}  // namespace cslam
