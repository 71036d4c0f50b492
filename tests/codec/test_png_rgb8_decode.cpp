// decode_png_rgb8 (libdeflate) against cv::imdecode(IMREAD_COLOR): synthetic colour images
// written by OpenCV's libpng at every compression level and strategy, PNGs built here with each
// row filter 0-4, the metadata chunks OpenCV does not apply, other PNG kinds (refused), damaged
// files (refused, never a crash), threads sharing the 16-bit decoder's scratch, and
// load_colour_image on a file.
#include <array>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>

#include <gtest/gtest.h>
#include <libdeflate.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "codec/image_codec.h"
#include "codec/png16_decode.h"
#include "codec/png16_fixtures.h"
#include "codec/png_rgb8_decode.h"
#include "common/run_program.h"
#include "core/error.h"
#include "io/tum_dataset.h"

namespace cslam {
namespace {

using namespace cslam::test;

// Colour content: "random" (noise in every channel), "smooth" (per-channel gradients with a
// little noise, a disc and a step, like a camera image), "flat" (one colour: long runs).
cv::Mat synthetic_bgr(int w, int h, const std::string& kind, unsigned seed) {
  cv::Mat im(h, w, CV_8UC3);
  cv::RNG rng(seed);
  if (kind == "random") {
    rng.fill(im, cv::RNG::UNIFORM, 0, 256);
  } else if (kind == "flat") {
    im.setTo(cv::Scalar(17, 200, 93));
  } else {
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const int n = rng.uniform(0, 6);
        im.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<std::uint8_t>(40 + x / 3 + n),
                                           cv::saturate_cast<std::uint8_t>(90 + y / 2 + n + (x > w / 2 ? 60 : 0)),
                                           cv::saturate_cast<std::uint8_t>(220 - (x + y) / 5 - n));
      }
    cv::circle(im, cv::Point(w / 3, h / 2), std::max(1, h / 4), cv::Scalar(250, 10, 128), cv::FILLED);
  }
  return im;
}

cv::Mat opencv_decode(const Bytes& png) { return cv::imdecode(png, cv::IMREAD_COLOR); }

void expect_identical(const cv::Mat& got, const cv::Mat& expected) {
  ASSERT_EQ(expected.type(), CV_8UC3);
  ASSERT_EQ(got.type(), CV_8UC3);
  ASSERT_EQ(got.size(), expected.size());
  EXPECT_EQ(cv::norm(got, expected, cv::NORM_INF), 0.0);
}

bool decodes(const Bytes& png, cv::Mat& out, std::string* why = nullptr) {
  return decode_png_rgb8(png.data(), png.size(), out, why);
}

Bytes rgb_png(const cv::Mat& bgr, const std::vector<int>& filters, int level = 6, std::size_t idat_chunk = 8192,
              const Chunks& before = {}, const Chunks& after = {}) {
  return build_png(ihdr(bgr.cols, bgr.rows, 8, 2), zlib_compress(filter_rows_rgb8(bgr, filters), level), idat_chunk,
                   before, after);
}

// ---- Tests ----

// The vector kernel's Paeth on unsigned bytes (|a + b - 2c| from |b - c| and |a - c|, saturated)
// against the spec, for all 2^24 inputs.
TEST(PngRgb8Decode, BytePaethPredictorMatchesTheSpecForAllInputs) {
  Bytes a(256 * 256), b(256 * 256), c(256 * 256), out(256 * 256);
  for (int i = 0; i < 256 * 256; ++i) {
    b[std::size_t(i)] = std::uint8_t(i >> 8);
    c[std::size_t(i)] = std::uint8_t(i);
  }
  int mismatches = 0;
  for (int av = 0; av < 256; ++av) {
    std::fill(a.begin(), a.end(), std::uint8_t(av));
    png_rgb8_detail::paeth_predict(a.data(), b.data(), c.data(), out.data(), out.size());
    for (std::size_t i = 0; i < out.size(); ++i)
      if (out[i] != paeth_reference(av, b[i], c[i])) ++mismatches;
  }
  EXPECT_EQ(mismatches, 0);
}

// The SSE4.1 kernel (eight rows at once, every filter) against the scalar one, on random filtered
// data: every band shape (1-7 rows left over) and narrow widths. Filter bytes: random 0-4; 0-2
// only (bands of such rows go to the scalar loops); bands of 0-2 and of 3-4 rows in turn.
TEST(PngRgb8Decode, VectorAndScalarUnfilteringAgree) {
  std::mt19937 rng(5);
  const auto filter_byte = [&](int mode, std::size_t y) {
    if (mode == 0) return std::uint8_t(rng() % 5);
    if (mode == 1 || (y / 8) % 2 == 0) return std::uint8_t(rng() % 3);
    return std::uint8_t(3 + rng() % 2);
  };
  for (int mode = 0; mode < 3; ++mode)
    for (int h = 1; h <= 27; ++h)
      for (int w : {1, 2, 3, 4, 5, 6, 7, 8, 9, 64, 641}) {
        const std::size_t stride = 1 + 3 * std::size_t(w);
        Bytes rows(std::size_t(h) * stride);
        for (std::size_t i = 0; i < rows.size(); ++i)
          rows[i] = i % stride == 0 ? filter_byte(mode, i / stride) : std::uint8_t(rng());
        cv::Mat simd(h, w, CV_8UC3), scalar(h, w, CV_8UC3);
        png_rgb8_detail::unfilter_rows(rows.data(), w, h, simd, true);
        png_rgb8_detail::unfilter_rows(rows.data(), w, h, scalar, false);
        ASSERT_EQ(cv::norm(simd, scalar, cv::NORM_INF), 0.0) << w << "x" << h << " mode " << mode;
      }
}

// OpenCV's encoder (libpng + zlib) at every level 0-9 with every strategy, and its default; all
// five filter types must occur among the rows libpng wrote.
TEST(PngRgb8Decode, OpenCvEncodedPngsDecodeIdentically) {
  check_opencv_encoded(
      3, synthetic_bgr, [](const Bytes& png, cv::Mat& got, std::string* why) { return decodes(png, got, why); },
      opencv_decode, expect_identical);
}

// A TUM-sized image with OpenCV's default settings (Sub filter, zlib level 1, RLE) and with zlib's
// default strategy at levels 6 and 9 (adaptive filters).
TEST(PngRgb8Decode, FullSizeColourImageFromOpenCv) {
  const cv::Mat im = synthetic_bgr(640, 480, "smooth", 3);
  for (const std::vector<int>& params :
       {std::vector<int>{}, std::vector<int>{cv::IMWRITE_PNG_COMPRESSION, 6, cv::IMWRITE_PNG_STRATEGY, 0},
        std::vector<int>{cv::IMWRITE_PNG_COMPRESSION, 9, cv::IMWRITE_PNG_STRATEGY, 0}}) {
    Bytes png;
    ASSERT_TRUE(cv::imencode(".png", im, png, params));
    cv::Mat got;
    std::string why;
    ASSERT_TRUE(decodes(png, got, &why)) << why;
    expect_identical(got, opencv_decode(png));
    expect_identical(got, im);
  }
}

// Each filter type alone, and all five mixed, written here; level 0 gives stored blocks.
TEST(PngRgb8Decode, EveryFilterTypeDecodesIdentically) {
  const std::vector<std::vector<int>> filter_sets = {{0}, {1}, {2}, {3}, {4}, {0, 1, 2, 3, 4}, {4, 3, 2, 1, 0}};
  for (const Size2& s : std::vector<Size2>{{1, 1}, {1, 5}, {2, 3}, {5, 4}, {31, 9}, {640, 8}})
    for (const std::string kind : {"random", "smooth"})
      for (const auto& filters : filter_sets)
        for (int level : {0, 1, 6, 12}) {
          const cv::Mat im = synthetic_bgr(s.w, s.h, kind, unsigned(s.w + 7 * s.h));
          const Bytes png = rgb_png(im, filters, level, 1000);
          const std::vector<int> written = row_filters(png, s.w, s.h, 3);
          for (int y = 0; y < s.h; ++y) ASSERT_EQ(written[std::size_t(y)], filters[std::size_t(y) % filters.size()]);
          cv::Mat got;
          std::string why;
          ASSERT_TRUE(decodes(png, got, &why)) << why;
          expect_identical(got, opencv_decode(png));
          expect_identical(got, im);
        }
}

// The metadata chunks the decoder skips, with values that would change pixels if OpenCV applied
// them (gamma 1.0 and 2.2, 5-6-5 significant bits, a background, a colour space): OpenCV decodes
// the image as written, and so does decode_png_rgb8.
TEST(PngRgb8Decode, IgnorableChunksAndOddChunkingDecodeIdentically) {
  const cv::Mat im = synthetic_bgr(37, 21, "smooth", 8);
  const Chunks meta = {{"gAMA", {0, 1, 0x86, 0xa0}},  // gamma 1.0
                       {"cHRM", Bytes(32, 7)},           {"sBIT", {5, 6, 5}},
                       {"bKGD", {0, 255, 0, 0, 0, 255}}, {"pHYs", {0, 0, 0x0b, 0x13, 0, 0, 0x0b, 0x13, 1}},
                       {"tEXt", {'K', 'e', 'y', 0, 'v'}}};
  const Chunks srgb = {{"sRGB", {0}}, {"gAMA", {0, 0, 0xb1, 0x8f}}};
  for (const Bytes& png : {rgb_png(im, {4, 1}, 6, 1, meta, {{"tEXt", {'a', 0, 'b'}}}),  // one-byte IDATs
                           rgb_png(im, {2, 3}, 6, 100000, srgb, {{"tIME", {7, 0xe9, 1, 2, 3, 4, 5}}})}) {
    cv::Mat got;
    std::string why;
    ASSERT_TRUE(decodes(png, got, &why)) << why;
    expect_identical(got, opencv_decode(png));
    expect_identical(got, im);
  }
  // Empty IDAT chunks between the others, and bytes after IEND (libpng does not read them).
  const Bytes z = zlib_compress(filter_rows_rgb8(im, {3}), 6);
  Bytes png = build_png(ihdr(37, 21, 8, 2), z, 50, {{"IDAT", {}}});
  png.insert(png.end(), {1, 2, 3});
  cv::Mat got;
  ASSERT_TRUE(decodes(png, got));
  expect_identical(got, opencv_decode(png));
}

void expect_refused(const Bytes& png, const std::string& what) {
  cv::Mat out(2, 3, CV_8UC1, cv::Scalar(7));
  std::string why;
  EXPECT_FALSE(decodes(png, out, &why)) << what;
  EXPECT_FALSE(why.empty()) << what;
  EXPECT_EQ(out.type(), CV_8UC1) << what;  // untouched
  EXPECT_EQ(out.at<std::uint8_t>(1, 2), 7) << what;
}

TEST(PngRgb8Decode, OtherPngKindsAreLeftToOpenCv) {
  const cv::Mat bgr = synthetic_bgr(20, 10, "smooth", 1);
  cv::Mat grey8, grey16, bgr16, bgra;
  cv::cvtColor(bgr, grey8, cv::COLOR_BGR2GRAY);
  grey8.convertTo(grey16, CV_16U, 257);
  bgr.convertTo(bgr16, CV_16U, 257);
  cv::cvtColor(bgr, bgra, cv::COLOR_BGR2BGRA);
  for (const cv::Mat& im : {grey8, grey16, bgr16, bgra}) {
    Bytes png;
    ASSERT_TRUE(cv::imencode(".png", im, png));
    expect_refused(png, "OpenCV type " + std::to_string(im.type()));
  }
  const Bytes z = zlib_compress(filter_rows_rgb8(bgr, {0}), 6);
  expect_refused(build_png(ihdr(20, 10, 8, 2, 1), z, 8192), "interlaced");
  expect_refused(build_png(ihdr(20, 10, 16, 2), z, 8192), "16-bit RGB header");
  expect_refused(build_png(ihdr(20, 10, 8, 6), z, 8192), "RGBA header");
  expect_refused(build_png(ihdr(20, 10, 8, 3), z, 8192, {{"PLTE", {0, 0, 0}}}), "palette");
  expect_refused(build_png(ihdr(20, 10, 8, 2), z, 8192, {{"PLTE", {0, 0, 0}}}), "suggested palette");
  expect_refused(build_png(ihdr(20, 10, 8, 2), z, 8192, {{"tRNS", {0, 1, 0, 2, 0, 3}}}), "tRNS");
  expect_refused(build_png(ihdr(20, 10, 8, 2), z, 8192, {{"iCCP", {'p', 0, 0, 0x78, 0x9c, 3, 0, 0, 0, 0, 1}}}), "iCCP");
  expect_refused(build_png(ihdr(20, 10, 8, 2), z, 8192, {{"eXIf", {'M', 'M', 0, 42, 0, 0, 0, 8}}}), "eXIf");
  expect_refused(build_png(ihdr(20, 10, 8, 2), z, 8192, {{"prIv", {1}}}), "unknown ancillary chunk");
  expect_refused(build_png(ihdr(20, 10, 8, 2), z, 8192, {{"zTXt", {'a', 0, 0, 0x78, 0x9c, 3, 0, 0, 0, 0, 1}}}), "zTXt");
  // And the 16-bit decoder leaves RGB to OpenCV (they share the chunk walk).
  Bytes png;
  ASSERT_TRUE(cv::imencode(".png", bgr, png));
  cv::Mat depth;
  EXPECT_FALSE(decode_png16_gray(png.data(), png.size(), depth));
}

TEST(PngRgb8Decode, DamagedFilesAreRefused) {
  const cv::Mat im = synthetic_bgr(24, 12, "smooth", 2);
  const Bytes good = rgb_png(im, {4, 1, 2, 3}, 6, 64);
  cv::Mat out;
  ASSERT_TRUE(decodes(good, out));
  check_damaged_container(good, expect_refused);
  Bytes b = good;
  const Bytes raw = filter_rows_rgb8(im, {4});
  Bytes adler = zlib_compress(raw, 6);
  adler.back() ^= 1;  // the stream's Adler-32, its last byte; the chunk's CRC is computed afterwards
  expect_refused(build_png(ihdr(24, 12, 8, 2), adler, 8192), "Adler-32 mismatch");
  Bytes bad_filter = raw;
  bad_filter[std::size_t(5) * (1 + 3 * 24)] = 5;
  expect_refused(build_png(ihdr(24, 12, 8, 2), zlib_compress(bad_filter, 6), 8192), "filter byte 5");
  Bytes extra = zlib_compress(raw, 6);
  extra.push_back(0);
  expect_refused(build_png(ihdr(24, 12, 8, 2), extra, 8192), "data after the zlib stream");
  Bytes longer = raw;
  longer.insert(longer.end(), 1 + 3 * 24, 0);  // one row too many
  expect_refused(build_png(ihdr(24, 12, 8, 2), zlib_compress(longer, 6), 8192), "too much image data");
  const Bytes shorter(raw.begin(), raw.end() - 1);
  expect_refused(build_png(ihdr(24, 12, 8, 2), zlib_compress(shorter, 6), 8192), "one byte of image data short");
  expect_refused(build_png(ihdr(24, 12, 8, 2), zlib_compress(raw, 6), 8192, {}, {{"tEXt", {'a', 0}}, {"IDAT", {}}}),
                 "IDAT chunks not consecutive");
  expect_refused(build_png(ihdr(9000, 1, 8, 2), zlib_compress(Bytes(27001, 0), 6), 8192), "wider than kMaxImageSide");
  expect_refused(build_png(ihdr(0, 1, 8, 2), zlib_compress(Bytes(1, 0), 6), 8192), "zero width");
}

// Random damage, with and without CRCs fixed up: never a crash, and whatever is accepted is
// exactly what OpenCV decodes (OpenCV must accept it too).
TEST(PngRgb8Decode, MutatedFilesNeverCrashOrDisagreeWithOpenCv) {
  const cv::Mat im = synthetic_bgr(40, 16, "smooth", 4);
  const Bytes valid = rgb_png(im, {0, 1, 2, 3, 4}, 6, 200);
  mutate_and_compare(
      valid, 19, [](const Bytes& b, cv::Mat& got) { return decodes(b, got); }, opencv_decode, expect_identical);
}

// Threads decoding colour and depth PNGs in turn: the two decoders share each thread's inflater
// and scratch buffers, of different sizes.
TEST(PngRgb8Decode, ManyThreadsAtOnceMixedWithDepth) {
  std::vector<Bytes> pngs;
  std::vector<cv::Mat> expected;
  for (int k = 0; k < 4; ++k) {
    Bytes png;
    const cv::Mat im = k % 2 ? synthetic_bgr(160 + k, 120, k % 4 == 1 ? "random" : "smooth", unsigned(k))
                             : synthetic_depth(170 + k, 100, "smooth", unsigned(k));
    ASSERT_TRUE(cv::imencode(".png", im, png, {cv::IMWRITE_PNG_COMPRESSION, 3 + k}));
    pngs.push_back(png);
    expected.push_back(im);
  }
  std::vector<int> mismatches(4, 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      for (int i = 0; i < 60; ++i) {
        const std::size_t k = std::size_t(t + i) % pngs.size();
        const Bytes& png = pngs[k];
        cv::Mat got;
        if (i % 7 == 0) decode_png_rgb8(png.data(), png.size() / 2, got);  // a failure in between
        const bool ok =
            k % 2 ? decode_png_rgb8(png.data(), png.size(), got) : decode_png16_gray(png.data(), png.size(), got);
        if (!ok || cv::norm(got, expected[k], cv::NORM_INF) != 0) ++mismatches[std::size_t(t)];
      }
    });
  for (auto& th : threads) th.join();
  for (int m : mismatches) EXPECT_EQ(m, 0);
}

// load_colour_image takes the fast path for an RGB PNG file and falls back to OpenCV for other
// PNGs: the same pixels as cv::imread either way; a damaged PNG is still an InputError.
TEST(PngRgb8Decode, LoadColourImageMatchesImread) {
  const TempDir dir("cslam_png_rgb8");
  const cv::Mat bgr = synthetic_bgr(641, 37, "smooth", 6);
  cv::Mat bgra, grey;
  cv::cvtColor(bgr, bgra, cv::COLOR_BGR2BGRA);
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  const std::vector<std::pair<std::string, cv::Mat>> files = {{"rgb.png", bgr}, {"bgra.png", bgra}, {"grey.png", grey}};
  for (const auto& [name, im] : files) {
    const std::string path = dir / name;
    ASSERT_TRUE(cv::imwrite(path, im));
    const cv::Mat got = load_colour_image(path);
    expect_identical(got, cv::imread(path, cv::IMREAD_COLOR));
  }
  expect_identical(load_colour_image(dir / "rgb.png"), bgr);
  Bytes png;
  ASSERT_TRUE(cv::imencode(".png", bgr, png));
  const std::string cut = dir / "cut.png";
  std::ofstream(cut, std::ios::binary).write(reinterpret_cast<const char*>(png.data()), 40);
  EXPECT_THROW(load_colour_image(cut), InputError);
}

}  // namespace
}  // namespace cslam
