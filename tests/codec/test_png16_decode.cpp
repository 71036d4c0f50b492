// decode_png16_gray (libdeflate) against cv::imdecode / cv::imread: PNGs written by OpenCV's
// libpng at every compression level and strategy, PNGs built here with each row filter 0-4, other
// PNG kinds (refused), damaged files (refused, never a crash), threads, and the real depth images.
#include <array>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <thread>

#include <gtest/gtest.h>
#include <libdeflate.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "codec/image_codec.h"
#include "codec/png16_decode.h"
#include "codec/png16_fixtures.h"
#include "common/test_data.h"

namespace cslam {
namespace {

using namespace cslam::test;

cv::Mat opencv_decode(const Bytes& png) { return cv::imdecode(png, cv::IMREAD_ANYDEPTH); }

void expect_identical(const cv::Mat& got, const cv::Mat& expected) {
  ASSERT_EQ(expected.type(), CV_16UC1);
  ASSERT_EQ(got.type(), CV_16UC1);
  ASSERT_EQ(got.size(), expected.size());
  EXPECT_EQ(cv::norm(got, expected, cv::NORM_INF), 0.0);
}

bool decodes(const Bytes& png, cv::Mat& out, std::string* why = nullptr) {
  return decode_png16_gray(png.data(), png.size(), out, why);
}

// ---- Tests ----

TEST(Png16Decode, PaethPredictorMatchesTheSpecForAllInputs) {
  int mismatches = 0;
  for (int a = 0; a < 256; ++a)
    for (int b = 0; b < 256; ++b)
      for (int c = 0; c < 256; ++c)
        if (png16_detail::paeth(a, b, c) != paeth_reference(a, b, c)) ++mismatches;
  EXPECT_EQ(mismatches, 0);
}

// The vector kernels undo the filters of `rows` (filter bytes and data, 2 * w bytes a row) exactly
// as the scalar one does.
void expect_kernels_agree(const Bytes& rows, int w, int h, const std::string& what) {
  using png16_detail::UnfilterPath;
  Bytes scratch = rows;
  cv::Mat scalar(h, w, CV_16UC1);
  png16_detail::unfilter_rows(scratch.data(), w, h, scalar, UnfilterPath::kScalar);
  for (UnfilterPath path : {UnfilterPath::kSse41, UnfilterPath::kAvx2}) {
    scratch = rows;
    cv::Mat vector(h, w, CV_16UC1);
    png16_detail::unfilter_rows(scratch.data(), w, h, vector, path);
    EXPECT_EQ(cv::norm(vector, scalar, cv::NORM_INF), 0.0) << what << ", path " << int(path);
  }
}

// The AVX2 (eight rows at once) and SSE4.1 (four) kernels against the scalar one, on random
// filtered data with random filter bytes: every band shape (1-8 rows left over) and narrow widths.
TEST(Png16Decode, VectorAndScalarUnfilteringAgree) {
  std::mt19937 rng(3);
  for (int h = 1; h <= 19; ++h)
    for (int w : {1, 2, 3, 4, 5, 7, 8, 9, 64, 641}) {
      Bytes rows(std::size_t(h) * (1 + 2 * std::size_t(w)));
      for (std::size_t i = 0; i < rows.size(); ++i)
        rows[i] = i % (1 + 2 * std::size_t(w)) == 0 ? std::uint8_t(rng() % 5) : std::uint8_t(rng());
      expect_kernels_agree(rows, w, h, std::to_string(w) + "x" + std::to_string(h));
    }
}

// Each filter type alone over whole bands (rows of one type, then of each type in turn): the
// vector kernels pick every row's predictor by lane masks, so a mask in the wrong lane shows here.
TEST(Png16Decode, VectorKernelsKeepEachRowsFilter) {
  std::mt19937 rng(4);
  const int w = 37, h = 24;
  for (int pattern = 0; pattern < 6; ++pattern) {
    Bytes rows(std::size_t(h) * (1 + 2 * std::size_t(w)));
    for (int y = 0; y < h; ++y) {
      std::uint8_t* row = rows.data() + std::size_t(y) * (1 + 2 * std::size_t(w));
      row[0] = std::uint8_t(pattern < 5 ? pattern : y % 5);
      for (int i = 1; i <= 2 * w; ++i) row[i] = std::uint8_t(rng());
    }
    expect_kernels_agree(rows, w, h, "pattern " + std::to_string(pattern));
  }
}

// OpenCV's encoder (libpng + zlib) at every level 0-9 with every strategy, and its default.
TEST(Png16Decode, OpenCvEncodedPngsDecodeIdentically) {
  check_opencv_encoded(
      2, synthetic_depth, [](const Bytes& png, cv::Mat& got, std::string* why) { return decodes(png, got, why); },
      opencv_decode, expect_identical);
}

TEST(Png16Decode, FullSizeDepthImageFromOpenCv) {
  const cv::Mat im = synthetic_depth(640, 480, "smooth", 3);
  for (const std::vector<int>& params : {std::vector<int>{}, std::vector<int>{cv::IMWRITE_PNG_COMPRESSION, 6}}) {
    Bytes png;
    ASSERT_TRUE(cv::imencode(".png", im, png, params));
    cv::Mat got;
    ASSERT_TRUE(decodes(png, got));
    expect_identical(got, opencv_decode(png));
  }
}

// Each filter type alone, and all five mixed, written here; level 0 gives stored blocks.
TEST(Png16Decode, EveryFilterTypeDecodesIdentically) {
  const std::vector<std::vector<int>> filter_sets = {{0}, {1}, {2}, {3}, {4}, {0, 1, 2, 3, 4}, {4, 3, 2, 1, 0}};
  for (const Size2& s : std::vector<Size2>{{1, 1}, {1, 5}, {2, 3}, {5, 4}, {31, 9}, {640, 8}})
    for (const std::string kind : {"random", "smooth"})
      for (const auto& filters : filter_sets)
        for (int level : {0, 1, 6, 12}) {
          const cv::Mat im = synthetic_depth(s.w, s.h, kind, unsigned(s.w + 7 * s.h));
          const Bytes png = hand_png(im, filters, level, 1000);
          cv::Mat got;
          std::string why;
          ASSERT_TRUE(decodes(png, got, &why)) << why;
          expect_identical(got, opencv_decode(png));
          expect_identical(got, im);
        }
}

TEST(Png16Decode, IgnorableChunksAndOddChunkingDecodeIdentically) {
  const cv::Mat im = synthetic_depth(37, 21, "smooth", 8);
  const Chunks meta = {{"gAMA", {0, 0, 0xb1, 0x8f}},
                       {"pHYs", {0, 0, 0x0b, 0x13, 0, 0, 0x0b, 0x13, 1}},
                       {"tEXt", {'K', 'e', 'y', 0, 'v'}},
                       {"sBIT", {12}}};
  for (const Bytes& png : {hand_png(im, {4, 1}, 6, 1, meta, {{"tEXt", {'a', 0, 'b'}}}),  // one-byte IDATs
                           hand_png(im, {2}, 6, 100000, {{"tIME", {7, 0xe9, 1, 2, 3, 4, 5}}})}) {
    cv::Mat got;
    std::string why;
    ASSERT_TRUE(decodes(png, got, &why)) << why;
    expect_identical(got, opencv_decode(png));
  }
  // Empty IDAT chunks between the others, and bytes after IEND (libpng does not read them).
  const Bytes z = zlib_compress(filter_rows(im, {3}), 6);
  Bytes png = build_png(ihdr(37, 21), z, 50, {{"IDAT", {}}});
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

TEST(Png16Decode, OtherPngKindsAreLeftToOpenCv) {
  const cv::Mat depth = synthetic_depth(20, 10, "smooth", 1);
  cv::Mat grey8, colour16, colour8;
  depth.convertTo(grey8, CV_8U, 1.0 / 256);
  cv::merge(std::vector<cv::Mat>{depth, depth, depth}, colour16);
  cv::cvtColor(grey8, colour8, cv::COLOR_GRAY2BGR);
  for (const cv::Mat& im : {grey8, colour16, colour8}) {
    Bytes png;
    ASSERT_TRUE(cv::imencode(".png", im, png));
    expect_refused(png, "OpenCV type " + std::to_string(im.type()));
  }
  const Bytes z = zlib_compress(filter_rows(depth, {0}), 6);
  expect_refused(build_png(ihdr(20, 10, 16, 0, 1), z, 8192), "interlaced");
  expect_refused(build_png(ihdr(20, 10, 16, 4), z, 8192), "grey + alpha");
  expect_refused(build_png(ihdr(20, 10, 8, 0), z, 8192), "8-bit header");
  expect_refused(build_png(ihdr(20, 10), z, 8192, {{"tRNS", {0, 0}}}), "tRNS");
  expect_refused(build_png(ihdr(20, 10), z, 8192, {{"eXIf", {'M', 'M', 0, 42, 0, 0, 0, 8}}}), "eXIf");
  expect_refused(build_png(ihdr(20, 10), z, 8192, {{"prIv", {1}}}), "unknown ancillary chunk");
  expect_refused(build_png(ihdr(20, 10), z, 8192, {{"PLTE", {0, 0, 0}}}), "PLTE");
}

TEST(Png16Decode, DamagedFilesAreRefused) {
  const cv::Mat im = synthetic_depth(24, 12, "smooth", 2);
  const Bytes good = hand_png(im, {4, 1, 2}, 6, 64);
  cv::Mat out;
  ASSERT_TRUE(decodes(good, out));
  check_damaged_container(good, expect_refused);
  Bytes b = good;
  const Bytes raw = filter_rows(im, {4});
  Bytes bad_filter = raw;
  bad_filter[std::size_t(5) * (1 + 2 * 24)] = 5;
  expect_refused(build_png(ihdr(24, 12), zlib_compress(bad_filter, 6), 8192), "filter byte 5");
  Bytes extra = zlib_compress(raw, 6);
  extra.push_back(0);
  expect_refused(build_png(ihdr(24, 12), extra, 8192), "data after the zlib stream");
  Bytes longer = raw;
  longer.insert(longer.end(), 49, 0);  // one row too many
  expect_refused(build_png(ihdr(24, 12), zlib_compress(longer, 6), 8192), "too much image data");
  expect_refused(build_png(ihdr(24, 12), zlib_compress(raw, 6), 8192, {}, {{"tEXt", {'a', 0}}, {"IDAT", {}}}),
                 "IDAT chunks not consecutive");
  expect_refused(build_png(ihdr(9000, 1), zlib_compress(Bytes(18001, 0), 6), 8192), "wider than kMaxImageSide");
}

// The zlib stream of `raw` after `empty_blocks` empty stored blocks: valid, but longer than any
// encoder writes it.
Bytes padded_zlib(const Bytes& raw, std::size_t empty_blocks) {
  Bytes z = {0x78, 0x01};
  for (std::size_t i = 0; i < empty_blocks; ++i) z.insert(z.end(), {0x00, 0x00, 0x00, 0xff, 0xff});
  libdeflate_compressor* c = libdeflate_alloc_compressor(6);
  Bytes body(libdeflate_deflate_compress_bound(c, raw.size()));
  body.resize(libdeflate_deflate_compress(c, raw.data(), raw.size(), body.data(), body.size()));
  libdeflate_free_compressor(c);
  z.insert(z.end(), body.begin(), body.end());
  put32(z, libdeflate_adler32(1, raw.data(), raw.size()));
  return z;
}

// The image data may exceed the inflated image by 1/8 + 1024 bytes (what fixed Huffman codes can
// need); beyond that the decoder leaves the file to OpenCV, which decodes it: the cap bounds the
// one uninterruptible libdeflate call on data from a peer, and no real file reaches it.
TEST(Png16Decode, ImageDataFarLongerThanTheImageIsLeftToOpenCv) {
  const cv::Mat im = synthetic_depth(24, 12, "smooth", 5);
  const Bytes raw = filter_rows(im, {1, 4});
  const std::size_t cap = raw.size() + raw.size() / 8 + 1024;       // 12 x 49 = 588 bytes inflated
  const std::size_t fits = (cap - padded_zlib(raw, 0).size()) / 5;  // empty blocks of 5 bytes
  cv::Mat out;
  const Bytes at_cap = build_png(ihdr(24, 12), padded_zlib(raw, fits), 8192);
  ASSERT_TRUE(decodes(at_cap, out));
  expect_identical(out, opencv_decode(at_cap));
  const Bytes past_cap = build_png(ihdr(24, 12), padded_zlib(raw, fits + 1), 8192);
  expect_refused(past_cap, "image data past the cap");
  std::string why;
  EXPECT_FALSE(decodes(past_cap, out, &why));
  EXPECT_NE(why.find("more image data"), std::string::npos) << why;
  expect_identical(opencv_decode(past_cap), im);
}

// Random damage, with and without CRCs fixed up: never a crash, and whatever is accepted is
// exactly what OpenCV decodes (OpenCV must accept it too).
TEST(Png16Decode, MutatedFilesNeverCrashOrDisagreeWithOpenCv) {
  const cv::Mat im = synthetic_depth(40, 16, "smooth", 4);
  const Bytes valid = hand_png(im, {0, 1, 2, 3, 4}, 6, 200);
  mutate_and_compare(
      valid, 17, [](const Bytes& b, cv::Mat& got) { return decodes(b, got); }, opencv_decode, expect_identical);
}

TEST(Png16Decode, ManyThreadsAtOnce) {
  std::vector<Bytes> pngs;
  std::vector<cv::Mat> expected;
  for (int k = 0; k < 4; ++k) {
    Bytes png;
    ASSERT_TRUE(cv::imencode(".png", synthetic_depth(160 + k, 120, k % 2 ? "random" : "smooth", unsigned(k)), png,
                             {cv::IMWRITE_PNG_COMPRESSION, 3 + k}));
    pngs.push_back(png);
    expected.push_back(opencv_decode(png));
  }
  std::vector<int> mismatches(4, 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      for (int i = 0; i < 60; ++i) {
        const std::size_t k = std::size_t(t + i) % pngs.size();
        cv::Mat got;
        if (i % 7 == 0) decode_png16_gray(pngs[k].data(), pngs[k].size() / 2, got);  // a failure in between
        if (!decode_png16_gray(pngs[k].data(), pngs[k].size(), got) || cv::norm(got, expected[k], cv::NORM_INF) != 0)
          ++mismatches[std::size_t(t)];
      }
    });
  for (auto& th : threads) th.join();
  for (int m : mismatches) EXPECT_EQ(m, 0);
}

// The dataset's own depth images: the first 50 of fr1/rpy and fr1/desk, bit for bit as cv::imread.
void check_dataset_depth(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::path(CSLAM_SHARED_DATA_DIR) / name / "depth";
  if (!std::filesystem::is_directory(dir)) {
    if (test::running_in_ci()) FAIL() << "real sequence missing: " << dir;
    GTEST_SKIP() << "real sequence not found at " << dir;
  }
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().extension() == ".png") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  ASSERT_GE(files.size(), 50u);
  for (std::size_t i = 0; i < 50; ++i) {
    std::ifstream in(files[i], std::ios::binary);
    const Bytes bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    cv::Mat got;
    std::string why;
    ASSERT_TRUE(decodes(bytes, got, &why)) << files[i] << ": " << why;
    expect_identical(got, cv::imread(files[i].string(), cv::IMREAD_ANYDEPTH));
  }
}

TEST(Png16Decode, TumRpyDepthImagesMatchImread) { check_dataset_depth("tum_fr1_rpy"); }
TEST(Png16Decode, TumDeskDepthImagesMatchImread) { check_dataset_depth("tum_fr1_desk"); }

}  // namespace
}  // namespace cslam
