#pragma once
// Synthetic 16-bit images and PNG byte streams (16-bit grey or 8-bit RGB) built by hand for the
// PNG decoder tests: each row filtered with a chosen filter type by a plain reference filter,
// compressed with libdeflate, split into IDAT chunks, with extra chunks where a test wants them.
#include <algorithm>
#include <array>
#include <cstdlib>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <libdeflate.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "codec/image_codec.h"

namespace cslam::test {

// Depth-like content: "random" (full 16-bit noise), "smooth" (gradients, blobs, a step and zero
// holes, like a depth image), "flat" (one value: long runs).
inline cv::Mat synthetic_depth(int w, int h, const std::string& kind, unsigned seed) {
  cv::Mat im(h, w, CV_16UC1);
  cv::RNG rng(seed);
  if (kind == "random") {
    rng.fill(im, cv::RNG::UNIFORM, 0, 65536);
  } else if (kind == "flat") {
    im.setTo(4321);
  } else {
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        im.at<std::uint16_t>(y, x) =
            std::uint16_t(5000 + 37 * x + 11 * y + int(rng.uniform(0, 8)) + (x > w / 2 ? 9000 : 0));
    cv::circle(im, cv::Point(w / 3, h / 2), std::max(1, h / 4), cv::Scalar(0), cv::FILLED);
  }
  return im;
}

inline void put32(Bytes& b, std::uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) b.push_back(std::uint8_t(v >> s));
}

inline void add_chunk(Bytes& png, const char* type, const Bytes& body) {
  put32(png, std::uint32_t(body.size()));
  const std::size_t start = png.size();
  png.insert(png.end(), type, type + 4);
  png.insert(png.end(), body.begin(), body.end());
  put32(png, libdeflate_crc32(0, png.data() + start, png.size() - start));
}

inline Bytes ihdr(int w, int h, int bit_depth = 16, int colour_type = 0, int interlace = 0) {
  Bytes b;
  put32(b, std::uint32_t(w));
  put32(b, std::uint32_t(h));
  b.insert(b.end(), {std::uint8_t(bit_depth), std::uint8_t(colour_type), 0, 0, std::uint8_t(interlace)});
  return b;
}

inline Bytes zlib_compress(const Bytes& raw, int level) {
  libdeflate_compressor* c = libdeflate_alloc_compressor(level);
  Bytes out(libdeflate_zlib_compress_bound(c, raw.size()));
  out.resize(libdeflate_zlib_compress(c, raw.data(), raw.size(), out.data(), out.size()));
  libdeflate_free_compressor(c);
  return out;
}

// The spec's Paeth predictor, written as the spec states it.
inline int paeth_reference(int a, int b, int c) {
  const int p = a + b - c;
  const int pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  if (pa <= pb && pa <= pc) return a;
  if (pb <= pc) return b;
  return c;
}

// Filtered image data: each row of `raw` (unfiltered PNG bytes, bpp bytes per pixel) with filter
// filters[y % size].
inline Bytes filter_raw_rows(const std::vector<Bytes>& raw, int bpp, const std::vector<int>& filters) {
  Bytes out;
  if (raw.empty()) return out;
  const int n = int(raw[0].size());
  Bytes zeros(std::size_t(n), 0);
  const Bytes* prior = &zeros;
  for (std::size_t y = 0; y < raw.size(); ++y) {
    const Bytes& row = raw[y];
    const int f = filters[y % filters.size()];
    out.push_back(std::uint8_t(f));
    for (int i = 0; i < n; ++i) {
      const int a = i >= bpp ? row[std::size_t(i - bpp)] : 0, b = (*prior)[std::size_t(i)];
      const int c = i >= bpp ? (*prior)[std::size_t(i - bpp)] : 0;
      const int pred = f == 0 ? 0 : f == 1 ? a : f == 2 ? b : f == 3 ? (a + b) / 2 : paeth_reference(a, b, c);
      out.push_back(std::uint8_t(row[std::size_t(i)] - pred));
    }
    prior = &row;
  }
  return out;
}

// Filtered image data of a CV_16UC1 image, row y with filter filters[y % size] (bpp = 2).
inline Bytes filter_rows(const cv::Mat& im, const std::vector<int>& filters) {
  std::vector<Bytes> raw(std::size_t(im.rows), Bytes(2 * std::size_t(im.cols)));
  for (int y = 0; y < im.rows; ++y)
    for (int x = 0; x < im.cols; ++x) {
      raw[std::size_t(y)][2 * std::size_t(x)] = std::uint8_t(im.at<std::uint16_t>(y, x) >> 8);
      raw[std::size_t(y)][2 * std::size_t(x) + 1] = std::uint8_t(im.at<std::uint16_t>(y, x) & 0xff);
    }
  return filter_raw_rows(raw, 2, filters);
}

// Filtered image data of a CV_8UC3 BGR image as an RGB PNG's (bpp = 3).
inline Bytes filter_rows_rgb8(const cv::Mat& bgr, const std::vector<int>& filters) {
  std::vector<Bytes> raw(std::size_t(bgr.rows), Bytes(3 * std::size_t(bgr.cols)));
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x)
      for (int k = 0; k < 3; ++k)
        raw[std::size_t(y)][3 * std::size_t(x) + std::size_t(k)] = bgr.at<cv::Vec3b>(y, x)[2 - k];
  return filter_raw_rows(raw, 3, filters);
}

// A PNG: signature, IHDR, `before` chunks, the zlib stream in IDATs of `idat_chunk` bytes, `after` chunks, IEND.
using Chunks = std::vector<std::pair<std::string, Bytes>>;
inline Bytes build_png(const Bytes& header, const Bytes& zlib, std::size_t idat_chunk, const Chunks& before = {},
                       const Chunks& after = {}) {
  Bytes png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  add_chunk(png, "IHDR", header);
  for (const auto& [type, body] : before) add_chunk(png, type.c_str(), body);
  for (std::size_t p = 0; p < zlib.size(); p += idat_chunk)
    add_chunk(png, "IDAT", Bytes(zlib.begin() + long(p), zlib.begin() + long(std::min(zlib.size(), p + idat_chunk))));
  for (const auto& [type, body] : after) add_chunk(png, type.c_str(), body);
  add_chunk(png, "IEND", {});
  return png;
}

inline Bytes hand_png(const cv::Mat& im, const std::vector<int>& filters, int level = 6, std::size_t idat_chunk = 8192,
                      const Chunks& before = {}, const Chunks& after = {}) {
  return build_png(ihdr(im.cols, im.rows), zlib_compress(filter_rows(im, filters), level), idat_chunk, before, after);
}

// Recomputes every chunk's CRC (to get past the CRC check to the later ones); stops at bad lengths.
inline void fix_crcs(Bytes& png) {
  for (std::size_t pos = 8; pos + 12 <= png.size();) {
    const std::size_t len = (std::size_t(png[pos]) << 24) | (png[pos + 1] << 16) | (png[pos + 2] << 8) | png[pos + 3];
    if (len > png.size() - pos - 12) return;
    const std::uint32_t crc = libdeflate_crc32(0, png.data() + pos + 4, len + 4);
    for (int k = 0; k < 4; ++k) png[pos + 8 + len + std::size_t(k)] = std::uint8_t(crc >> (24 - 8 * k));
    pos += 12 + len;
  }
}

// The image sizes the encoder tests sweep: single pixels, single rows and columns, odd widths.
struct Size2 {
  int w, h;
};
inline const std::vector<Size2> kSizes = {{1, 1}, {1, 9}, {9, 1}, {3, 5}, {17, 6}, {33, 17}, {64, 48}};

// The filter byte of every row of a PNG with `bytes_per_pixel` (all IDATs inflated once more
// here); empty if the data does not inflate.
inline std::vector<int> row_filters(const Bytes& png, int w, int h, int bytes_per_pixel) {
  Bytes z;
  for (std::size_t pos = 8; pos + 12 <= png.size();) {
    const std::size_t len = (std::size_t(png[pos]) << 24) | (png[pos + 1] << 16) | (png[pos + 2] << 8) | png[pos + 3];
    if (std::string(png.begin() + long(pos) + 4, png.begin() + long(pos) + 8) == "IDAT")
      z.insert(z.end(), png.begin() + long(pos) + 8, png.begin() + long(pos + 8 + len));
    pos += 12 + len;
  }
  const std::size_t stride = 1 + std::size_t(bytes_per_pixel) * std::size_t(w);
  Bytes raw(std::size_t(h) * stride);
  libdeflate_decompressor* dec = libdeflate_alloc_decompressor();
  const libdeflate_result rc = libdeflate_zlib_decompress(dec, z.data(), z.size(), raw.data(), raw.size(), nullptr);
  libdeflate_free_decompressor(dec);
  std::vector<int> filters;
  if (rc != LIBDEFLATE_SUCCESS) return filters;
  for (int y = 0; y < h; ++y) filters.push_back(raw[std::size_t(y) * stride]);
  return filters;
}

// OpenCV's encoder (libpng + zlib) at every level 0-9 with every strategy, and its default, over
// kSizes and three kinds of content (`synth(w, h, kind, seed)`): `decodes` must give OpenCV's and
// the original pixels (`same`), and all five filter types must occur among the rows libpng wrote.
template <class Synth, class Decodes, class Reference, class Same>
void check_opencv_encoded(int bytes_per_pixel, Synth synth, Decodes decodes, Reference reference, Same same) {
  std::array<int, 5> filter_rows_seen{};
  int cases = 0;
  for (const Size2& s : kSizes)
    for (const std::string kind : {"random", "smooth", "flat"})
      for (int level = -1; level <= 9; ++level)
        for (int strategy = 0; strategy <= 4; ++strategy) {
          if (level == -1 && strategy > 0) continue;
          const cv::Mat im = synth(s.w, s.h, kind, unsigned(s.w * 131 + s.h));
          std::vector<int> params;
          if (level >= 0) params = {cv::IMWRITE_PNG_COMPRESSION, level, cv::IMWRITE_PNG_STRATEGY, strategy};
          Bytes png;
          ASSERT_TRUE(cv::imencode(".png", im, png, params));
          cv::Mat got;
          std::string why;
          ASSERT_TRUE(decodes(png, got, &why)) << s.w << "x" << s.h << " " << kind << " level " << level << ": " << why;
          same(got, reference(png));
          same(got, im);
          ++cases;
          const std::vector<int> filters = row_filters(png, s.w, s.h, bytes_per_pixel);
          ASSERT_EQ(filters.size(), std::size_t(s.h));
          for (int f : filters) ++filter_rows_seen[std::size_t(f % 5)];
        }
  EXPECT_EQ(cases, int(kSizes.size()) * 3 * 51);
  for (int f = 0; f < 5; ++f) EXPECT_GT(filter_rows_seen[std::size_t(f)], 0) << "libpng never chose filter " << f;
}

// Damage to the container of `good` (a 24-pixel-wide PNG whose first IDAT holds more than 20
// bytes) that a decoder must refuse: every truncation, a flipped image-data byte (with and
// without its CRC fixed), a wrong width, a bad IHDR length and absurd chunk lengths.
template <class Refused>
void check_damaged_container(const Bytes& good, Refused expect_refused) {
  for (std::size_t keep = 0; keep < good.size(); ++keep)  // every truncation, IEND's last byte included
    expect_refused(Bytes(good.begin(), good.begin() + long(keep)), "truncated to " + std::to_string(keep));
  Bytes b = good;
  b[8 + 12 + 13 + 8 + 20] ^= 0x10;  // inside the first IDAT: its CRC fails
  expect_refused(b, "flipped IDAT byte");
  fix_crcs(b);
  expect_refused(b, "flipped IDAT byte, CRC fixed (inflate or Adler-32 fails)");
  b = good;
  b[19] = 25;  // width 25: the data inflates to too few bytes
  fix_crcs(b);
  expect_refused(b, "wrong width");
  b = good;
  b[8] = 0, b[11] = 14;  // IHDR length 14
  expect_refused(b, "IHDR length");
  for (const std::uint32_t len : {0xffffffffu, 0x7fffffffu, std::uint32_t(good.size())}) {
    b = good;
    for (int k = 0; k < 4; ++k) b[33 + std::size_t(k)] = std::uint8_t(len >> (24 - 8 * k));  // first IDAT's length
    expect_refused(b, "chunk length " + std::to_string(len));
  }
}

// Random damage to a valid PNG (1-4 bytes changed, every fifth also truncated), every second
// one with its CRCs fixed up so that the damage reaches the image data: `decodes` must never
// crash, and whatever it accepts, `reference` (OpenCV) must decode to the pixels `same` checks.
// Most mutations must be refused, and some accepted (changes to CRC fields that fix_crcs undoes).
template <class Decodes, class Reference, class Same>
void mutate_and_compare(const Bytes& valid, unsigned seed, Decodes decodes, Reference reference, Same same) {
  std::mt19937 rng(seed);
  int accepted = 0, refused = 0;
  for (int i = 0; i < 3000; ++i) {
    Bytes b = valid;
    std::uniform_int_distribution<std::size_t> pos(0, b.size() - 1);
    for (int k = 0; k < 1 + int(rng() % 4); ++k) b[pos(rng)] = std::uint8_t(rng());
    if (i % 5 == 0) b.resize(rng() % b.size());
    if (i % 2 == 0) fix_crcs(b);
    cv::Mat got;
    if (decodes(b, got)) {
      ++accepted;
      const cv::Mat expected = reference(b);
      ASSERT_FALSE(expected.empty()) << "accepted what OpenCV refuses, mutation " << i;
      same(got, expected);
    } else {
      ++refused;
    }
  }
  EXPECT_GT(refused, 2000);
  EXPECT_GT(accepted, 0);
}

}  // namespace cslam::test
