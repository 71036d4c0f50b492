// decode_jpeg_bgr (TurboJPEG) against cv::imdecode, and bad input. OpenCV 4.6 and TurboJPEG both
// use Debian 12's libjpeg-turbo 2.1.5 (libjpeg62-turbo / libturbojpeg0, one source package), so
// with the same decoder settings the pixels must be bit-identical, not merely close.
#include <random>
#include <thread>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <turbojpeg.h>

#include "codec/image_codec.h"
#include "codec/jpeg_decode.h"
#include "core/error.h"

namespace cslam {
namespace {

// Smooth colour gradients, sharp edges and noise: chroma upsampling and the IDCT both matter.
cv::Mat synthetic_bgr(int w, int h, unsigned seed) {
  cv::Mat im(h, w, CV_8UC3);
  cv::RNG rng(seed);
  rng.fill(im, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(im, im, cv::Size(7, 7), 2.0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      cv::Vec3b& p = im.at<cv::Vec3b>(y, x);
      p[0] = cv::saturate_cast<std::uint8_t>(p[0] / 2 + 255 * x / w / 2);
      p[2] = cv::saturate_cast<std::uint8_t>(p[2] / 2 + 255 * y / h / 2);
    }
  cv::rectangle(im, cv::Rect(w / 4, h / 4, w / 3, h / 3), cv::Scalar(20, 240, 60), cv::FILLED);
  cv::circle(im, cv::Point(w * 2 / 3, h / 2), h / 5, cv::Scalar(250, 30, 200), cv::FILLED);
  return im;
}

Bytes encode(const cv::Mat& im, const std::vector<int>& params) {
  Bytes out;
  EXPECT_TRUE(cv::imencode(".jpg", im, out, params));
  return out;
}

cv::Mat opencv_decode(const Bytes& jpeg) {
  return cv::imdecode(jpeg, cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
}

struct JpegCase {
  std::string name;
  int width, height;
  std::vector<int> params;
  bool grey;
};

class JpegMatchesOpenCv : public ::testing::TestWithParam<JpegCase> {};

TEST_P(JpegMatchesOpenCv, BitIdenticalToImdecode) {
  const JpegCase& c = GetParam();
  cv::Mat im = synthetic_bgr(c.width, c.height, 11);
  if (c.grey) cv::cvtColor(im, im, cv::COLOR_BGR2GRAY);
  const Bytes jpeg = encode(im, c.params);
  const cv::Mat expected = opencv_decode(jpeg);
  ASSERT_EQ(expected.type(), CV_8UC3);
  const cv::Mat got = decode_jpeg_bgr(jpeg.data(), jpeg.size(), "test");
  ASSERT_EQ(got.type(), CV_8UC3);
  ASSERT_EQ(got.size(), expected.size());
  EXPECT_EQ(cv::norm(got, expected, cv::NORM_INF), 0.0);
  // The same with the size given, as the network decoder calls it.
  const cv::Mat sized = decode_jpeg_bgr(jpeg.data(), jpeg.size(), "test", c.width, c.height);
  EXPECT_EQ(cv::norm(sized, expected, cv::NORM_INF), 0.0);
}

INSTANTIATE_TEST_SUITE_P(
    Variants, JpegMatchesOpenCv,
    ::testing::Values(JpegCase{"q75_640x480", 640, 480, {cv::IMWRITE_JPEG_QUALITY, 75}, false},
                      JpegCase{"q95", 160, 120, {cv::IMWRITE_JPEG_QUALITY, 95}, false},
                      JpegCase{"q30_odd_size", 37, 23, {cv::IMWRITE_JPEG_QUALITY, 30}, false},
                      JpegCase{"progressive", 96, 64, {cv::IMWRITE_JPEG_PROGRESSIVE, 1}, false},
                      JpegCase{"restart_markers", 96, 64, {cv::IMWRITE_JPEG_RST_INTERVAL, 2}, false},
                      JpegCase{"optimized_huffman", 96, 64, {cv::IMWRITE_JPEG_OPTIMIZE, 1}, false},
                      JpegCase{"separate_luma_chroma_quality",
                               96,
                               64,
                               {cv::IMWRITE_JPEG_LUMA_QUALITY, 90, cv::IMWRITE_JPEG_CHROMA_QUALITY, 40},
                               false},
                      JpegCase{"greyscale", 64, 48, {cv::IMWRITE_JPEG_QUALITY, 85}, true},
                      JpegCase{"one_pixel", 1, 1, {}, false}),
    [](const auto& info) { return info.param.name; });

// TurboJPEG cannot convert CMYK/YCCK to BGR; those go to cv::imdecode (same pixels as before).
TEST(JpegDecode, CmykJpegDecodesLikeOpenCv) {
  const int w = 32, h = 24;
  std::vector<std::uint8_t> cmyk(std::size_t(w) * h * 4);
  std::mt19937 rng(5);
  for (auto& v : cmyk) v = std::uint8_t(rng() % 256);
  tjhandle tj = tjInitCompress();
  unsigned char* buf = nullptr;
  unsigned long size = 0;
  ASSERT_EQ(tjCompress2(tj, cmyk.data(), w, w * 4, h, TJPF_CMYK, &buf, &size, TJSAMP_444, 90, 0), 0)
      << tjGetErrorStr2(tj);
  const Bytes jpeg(buf, buf + size);
  tjFree(buf);
  tjDestroy(tj);
  const cv::Mat expected = opencv_decode(jpeg);
  const cv::Mat got = decode_jpeg_bgr(jpeg.data(), jpeg.size(), "test", w, h);
  ASSERT_EQ(got.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(got, expected, cv::NORM_INF), 0.0);
}

void expect_input_error(const Bytes& bytes, std::size_t size, const std::string& what_part, int w = 0, int h = 0) {
  try {
    decode_jpeg_bgr(bytes.data(), size, "cam.jpg", w, h);
    ADD_FAILURE() << "accepted " << size << " of " << bytes.size() << " bytes";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cam.jpg"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(what_part), std::string::npos) << e.what();
  }
}

TEST(JpegDecode, WrongSizeIsRejectedBeforeDecoding) {
  const Bytes jpeg = encode(synthetic_bgr(64, 48, 1), {});
  expect_input_error(jpeg, jpeg.size(), "JPEG is 64x48, expected 32x48", 32, 48);
  expect_input_error(jpeg, jpeg.size(), "expected 64x47", 64, 47);
}

// Unlike cv::imdecode, which fills a truncated image with grey and returns it, every truncation
// is refused: libjpeg's "premature end of data" warning counts as corruption.
TEST(JpegDecode, EveryTruncationIsAnInputError) {
  const Bytes jpeg = encode(synthetic_bgr(96, 64, 2), {cv::IMWRITE_JPEG_QUALITY, 90});
  for (std::size_t keep : {std::size_t(0), std::size_t(1), std::size_t(2), std::size_t(3), std::size_t(20)})
    expect_input_error(jpeg, keep, "JPEG");
  for (std::size_t keep = 25; keep < jpeg.size(); keep += 37) expect_input_error(jpeg, keep, "JPEG");
  expect_input_error(jpeg, jpeg.size() - 2, "corrupt JPEG");  // only the end-of-image marker missing
  expect_input_error(jpeg, jpeg.size() - 1, "corrupt JPEG");
}

TEST(JpegDecode, GarbageAndDamagedHeadersAreInputErrors) {
  const Bytes garbage(500, 0xab);
  expect_input_error(garbage, garbage.size(), "not a JPEG image");
  Bytes soi_then_garbage = garbage;
  soi_then_garbage[0] = 0xff;
  soi_then_garbage[1] = 0xd8;
  soi_then_garbage[2] = 0xff;
  expect_input_error(soi_then_garbage, soi_then_garbage.size(), "corrupt JPEG");
  // Zero width in the frame header.
  Bytes jpeg = encode(synthetic_bgr(64, 48, 3), {});
  for (std::size_t i = 2; i + 8 < jpeg.size(); ++i)
    if (jpeg[i] == 0xff && jpeg[i + 1] == 0xc0) {
      jpeg[i + 7] = jpeg[i + 8] = 0;
      break;
    }
  expect_input_error(jpeg, jpeg.size(), "JPEG");
}

// Mutated files through the path local files take (no expected size, no header pre-check): an
// image of the size the header says, or InputError; never a crash.
TEST(JpegDecode, MutatedBytesNeverCrash) {
  const Bytes valid = encode(synthetic_bgr(48, 32, 4), {cv::IMWRITE_JPEG_QUALITY, 80});
  std::mt19937 rng(99);
  int rejected = 0;
  for (int i = 0; i < 2000; ++i) {
    Bytes b = valid;
    std::uniform_int_distribution<std::size_t> pos(0, b.size() - 1);
    for (int k = 0; k < 1 + int(rng() % 6); ++k) b[pos(rng)] = std::uint8_t(rng());
    if (i % 3 == 0) b.resize(rng() % b.size());
    try {
      const cv::Mat m = decode_jpeg_bgr(b.data(), b.size(), "fuzz");
      EXPECT_EQ(m.type(), CV_8UC3);
      EXPECT_LE(m.cols, kMaxImageSide);
      EXPECT_LE(m.rows, kMaxImageSide);
    } catch (const InputError&) {
      ++rejected;
    }
  }
  EXPECT_GT(rejected, 600);  // at least every truncated one
}

TEST(JpegDecode, DecoderIsUsableAfterAnErrorAndFromManyThreads) {
  const Bytes jpeg = encode(synthetic_bgr(128, 96, 6), {});
  const cv::Mat expected = opencv_decode(jpeg);
  // A bad header (libjpeg-turbo 2.1.5 leaves the decompressor inside it), a bad scan, then good data.
  Bytes bad_table(jpeg.begin(), jpeg.end());
  for (std::size_t i = 2; i + 4 < bad_table.size(); ++i)
    if (bad_table[i] == 0xff && bad_table[i + 1] == 0xc4) {  // first DHT: claim 255 codes of length 1
      bad_table[i + 5] = 0xff;
      break;
    }
  for (const std::size_t keep : {std::size_t(20), jpeg.size() / 2}) {
    EXPECT_THROW(decode_jpeg_bgr(jpeg.data(), keep, "t"), InputError);
    EXPECT_EQ(cv::norm(decode_jpeg_bgr(jpeg.data(), jpeg.size(), "t"), expected, cv::NORM_INF), 0.0);
  }
  EXPECT_THROW(decode_jpeg_bgr(bad_table.data(), bad_table.size(), "t"), InputError);
  EXPECT_EQ(cv::norm(decode_jpeg_bgr(jpeg.data(), jpeg.size(), "t"), expected, cv::NORM_INF), 0.0);
  std::vector<int> mismatches(4, 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      for (int i = 0; i < 50; ++i) {
        try {
          if (i % 5 == 0) decode_jpeg_bgr(jpeg.data(), jpeg.size() - 10, "t");
          if (i % 7 == 0) decode_jpeg_bgr(jpeg.data(), 20, "t");
        } catch (const InputError&) {
        }
        if (cv::norm(decode_jpeg_bgr(jpeg.data(), jpeg.size(), "t"), expected, cv::NORM_INF) != 0) ++mismatches[t];
      }
    });
  for (auto& th : threads) th.join();
  for (int m : mismatches) EXPECT_EQ(m, 0);
}

TEST(JpegDecode, LooksLikeJpeg) {
  const Bytes jpeg = encode(synthetic_bgr(8, 8, 7), {});
  EXPECT_TRUE(looks_like_jpeg(jpeg.data(), jpeg.size()));
  EXPECT_FALSE(looks_like_jpeg(jpeg.data(), 2));
  const std::uint8_t png[] = {0x89, 'P', 'N', 'G'};
  EXPECT_FALSE(looks_like_jpeg(png, sizeof png));
}

}  // namespace
}  // namespace cslam
