// Randomised decoder test: random and mutated bytes into every decoder, thousands of times.
// A decoder must either return an image of exactly the announced size or throw InputError.
#include <random>

#include <gtest/gtest.h>

#include <zlib.h>

#include "codec/image_codec.h"
#include "codec/image_encoder.h"
#include "codec/video_codec.h"
#include "core/error.h"

namespace cslam {
namespace {

constexpr int kW = 40, kH = 30;

Bytes mutate(Bytes bytes, std::mt19937& rng) {
  std::uniform_int_distribution<int> kind(0, 3), byte(0, 255);
  if (bytes.empty()) return bytes;
  switch (kind(rng)) {
    case 0: {  // flip a few bytes
      std::uniform_int_distribution<std::size_t> pos(0, bytes.size() - 1);
      for (int k = 0; k < 1 + int(rng() % 8); ++k) bytes[pos(rng)] = std::uint8_t(byte(rng));
      break;
    }
    case 1:
      bytes.resize(rng() % bytes.size());
      break;  // truncate
    case 2:
      bytes.insert(bytes.end(), 1 + rng() % 64, 0x55);
      break;    // trailing junk
    default: {  // splice a random block
      std::uniform_int_distribution<std::size_t> pos(0, bytes.size() - 1);
      const std::size_t at = pos(rng);
      for (std::size_t k = at; k < std::min(bytes.size(), at + 16); ++k) bytes[k] = std::uint8_t(byte(rng));
    }
  }
  return bytes;
}

void expect_sane_or_input_error(const std::function<cv::Mat()>& decode, int type) {
  try {
    const cv::Mat m = decode();
    EXPECT_EQ(m.cols, kW);
    EXPECT_EQ(m.rows, kH);
    EXPECT_EQ(m.type(), type);
  } catch (const InputError&) {
    // expected for most inputs
  }
}

TEST(CodecFuzz, MutatedAndRandomBytesNeverCrashAnyDecoder) {
  std::mt19937 rng(1234);
  cv::Mat bgr(kH, kW, CV_8UC3), depth(kH, kW, CV_16UC1);
  cv::RNG cvrng(7);
  cvrng.fill(bgr, cv::RNG::UNIFORM, 0, 256);
  cvrng.fill(depth, cv::RNG::UNIFORM, 0, 6000);
  int rgb_rejected = 0, depth_rejected = 0, iterations = 0;
  for (RgbCodec c : {RgbCodec::kRaw, RgbCodec::kJpeg, RgbCodec::kPng}) {
    CodecOptions o;
    o.rgb = c;
    const Bytes valid = encode_rgb(bgr, o);
    for (int i = 0; i < 600; ++i, ++iterations) {
      Bytes b = (i % 5 == 0) ? Bytes(rng() % 2000) : mutate(valid, rng);
      if (i % 5 == 0)
        for (auto& x : b) x = std::uint8_t(rng());
      try {
        decode_rgb(c, b.data(), b.size(), kW, kH, "fuzz");
      } catch (const InputError&) {
        ++rgb_rejected;
      }
    }
  }
  for (DepthCodec c : {DepthCodec::kRaw, DepthCodec::kPng, DepthCodec::kRvl, DepthCodec::kZstdDelta}) {
    CodecOptions o;
    o.depth = c;
    const Bytes valid = encode_depth(depth, o);
    for (int i = 0; i < 1000; ++i, ++iterations) {
      Bytes b = (i % 5 == 0) ? Bytes(rng() % 4000) : mutate(valid, rng);
      if (i % 5 == 0)
        for (auto& x : b) x = std::uint8_t(rng());
      expect_sane_or_input_error([&] { return decode_depth(c, b.data(), b.size(), kW, kH, "fuzz"); }, CV_16UC1);
      try {
        decode_depth(c, b.data(), b.size(), kW, kH, "fuzz");
      } catch (const InputError&) {
        ++depth_rejected;
      }
    }
  }
  EXPECT_EQ(iterations, 3 * 600 + 4 * 1000);
  // Most mutations must be caught (random bytes always are, except by the raw codecs of the right size).
  EXPECT_GT(rgb_rejected, 600);
  EXPECT_GT(depth_rejected, 1500);
}

// Standalone H.264 pictures: mutated packets (the header's CRC catches them), and mutated
// bitstreams behind a recomputed, valid header (libavcodec's own checks must catch them or
// return a picture of the right size).
TEST(CodecFuzz, MutatedH264PicturesNeverCrashTheDecoder) {
  std::mt19937 rng(99);
  cv::Mat bgr(kH + 2, kW, CV_8UC3);  // 40 x 32: even sides
  cv::RNG(8).fill(bgr, cv::RNG::UNIFORM, 0, 256);
  CodecOptions o;
  o.rgb = RgbCodec::kH264Intra;
  const Bytes valid = ImageEncoder(o).rgb(bgr);
  ASSERT_GT(valid.size(), video::kH264HeaderBytes + 16);
  int rejected = 0, decoded = 0;
  for (int i = 0; i < 600; ++i) {
    Bytes b = mutate(valid, rng);
    if (i % 2 == 1 && b.size() > video::kH264HeaderBytes) {  // a valid header over a damaged bitstream
      std::copy(valid.begin(), valid.begin() + 8, b.begin());
      const auto length = std::uint32_t(b.size() - video::kH264HeaderBytes);
      for (int k = 0; k < 4; ++k) b[8 + k] = std::uint8_t(length >> (8 * k));
      uLong crc = crc32(0L, b.data(), 12);
      crc = crc32(crc, b.data() + video::kH264HeaderBytes, uInt(length));
      for (int k = 0; k < 4; ++k) b[12 + k] = std::uint8_t(crc >> (8 * k));
    }
    try {
      const cv::Mat m = decode_rgb(o.rgb, b.data(), b.size(), kW, kH + 2, "fuzz");
      EXPECT_EQ(m.cols, kW);
      EXPECT_EQ(m.rows, kH + 2);
      EXPECT_EQ(m.type(), CV_8UC3);
      ++decoded;
    } catch (const InputError&) {
      ++rejected;
    }
  }
  EXPECT_EQ(rejected + decoded, 600);
  EXPECT_GT(rejected, 250);  // every packet with a damaged header or CRC at least
}

TEST(CodecFuzz, RandomBytesOfTheRightRawSizeDecode) {
  Bytes b(std::size_t(kW) * kH * 2, 0x11);
  const cv::Mat d = decode_depth(DepthCodec::kRaw, b.data(), b.size(), kW, kH, "fuzz");
  EXPECT_EQ(d.at<std::uint16_t>(0, 0), 0x1111);
}

}  // namespace
}  // namespace cslam
