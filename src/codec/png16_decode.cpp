#include "codec/png16_decode.h"

#include <algorithm>
#include <cstring>
#include <vector>

#include "codec/png_inflate.h"
#include "core/cpu_features.h"

#if defined(__SSE4_1__)
#include <smmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__) && defined(__SSE4_1__)
#include <immintrin.h>
#define CSLAM_PNG16_AVX2 1
#endif

namespace cslam {

namespace {

// Undoing the row filters, bpp = 2: a byte's "left" neighbour is 2 bytes back, so the high and
// low bytes of the pixels form two independent chains. Scalar version, in place: the fallback
// without SSE4.1 and the tests' second opinion on the vector version.
void unfilter_sub(std::uint8_t* cur, std::size_t n) {
  std::uint8_t a0 = cur[0], a1 = cur[1];
  for (std::size_t i = 2; i < n; i += 2) {
    a0 = std::uint8_t(cur[i] + a0);
    a1 = std::uint8_t(cur[i + 1] + a1);
    cur[i] = a0;
    cur[i + 1] = a1;
  }
}

void unfilter_up(std::uint8_t* __restrict cur, const std::uint8_t* __restrict prev, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) cur[i] = std::uint8_t(cur[i] + prev[i]);
}

void unfilter_average(std::uint8_t* __restrict cur, const std::uint8_t* __restrict prev, std::size_t n) {
  std::uint8_t a0 = std::uint8_t(cur[0] + (prev[0] >> 1)), a1 = std::uint8_t(cur[1] + (prev[1] >> 1));
  cur[0] = a0;
  cur[1] = a1;
  for (std::size_t i = 2; i < n; i += 2) {
    a0 = std::uint8_t(cur[i] + ((a0 + prev[i]) >> 1));
    a1 = std::uint8_t(cur[i + 1] + ((a1 + prev[i + 1]) >> 1));
    cur[i] = a0;
    cur[i + 1] = a1;
  }
}

void unfilter_paeth(std::uint8_t* __restrict cur, const std::uint8_t* __restrict prev, std::size_t n) {
  // First pixel: no left neighbour (a = c = 0), the predictor is the byte above.
  cur[0] = std::uint8_t(cur[0] + prev[0]);
  cur[1] = std::uint8_t(cur[1] + prev[1]);
  int a0 = cur[0], a1 = cur[1];
  for (std::size_t i = 2; i < n; i += 2) {
    a0 = std::uint8_t(cur[i] + png_detail::paeth(a0, prev[i], prev[i - 2]));
    a1 = std::uint8_t(cur[i + 1] + png_detail::paeth(a1, prev[i + 1], prev[i - 1]));
    cur[i] = std::uint8_t(a0);
    cur[i + 1] = std::uint8_t(a1);
  }
}

void unfilter_rows_scalar(std::uint8_t* rows, int width, int height, cv::Mat& out) {
  const std::size_t n = 2 * std::size_t(width);
  const std::vector<std::uint8_t> zeros(n, 0);
  const std::uint8_t* prev = zeros.data();
  for (int y = 0; y < height; ++y) {
    std::uint8_t* cur = rows + std::size_t(y) * (n + 1) + 1;
    switch (cur[-1]) {
      case 1:
        unfilter_sub(cur, n);
        break;
      case 2:
        unfilter_up(cur, prev, n);
        break;
      case 3:
        unfilter_average(cur, prev, n);
        break;
      case 4:
        unfilter_paeth(cur, prev, n);
        break;
      default:
        break;
    }
    std::uint16_t* dst = out.ptr<std::uint16_t>(y);
    for (int x = 0; x < width; ++x) dst[x] = std::uint16_t((cur[2 * x] << 8) | cur[2 * x + 1]);
    prev = cur;
  }
}

#if defined(__SSE4_1__)
// Four rows at once. Row r of a band sits in 16-bit lanes 2r (high byte) and 2r + 1 (low byte)
// and runs one pixel behind row r - 1, so its bytes "above" and "above-left" are row r - 1's
// results of the previous two steps (a lane shift, no memory) and the eight byte chains advance
// together. Each lane computes all predictors and keeps its row's: one kernel for every filter.
// Results go straight to the output as host-order uint16; row 0 reads the row above the band
// from there.
struct Band {
  const std::uint8_t* cur[4];  // filtered bytes of the band's rows
  std::uint16_t* dst[4];       // their output rows
  const std::uint16_t* above;  // the decoded row above the band
  int rows, width;
  __m128i sub, up, average, paeth;  // per-lane masks of the rows' filter types
};

// The rows of the band from row y0 (at most kRows): where each one's filtered bytes and output
// start, and its filter type as all-ones in its two 16-bit lanes of the mask of that type (sub,
// up, average, paeth; none: no mask). Returns the band's row count.
template <int kRows>
int band_rows(const std::uint8_t* rows, std::size_t stride, int y0, int height, cv::Mat& out,
              const std::uint8_t* (&cur)[kRows], std::uint16_t* (&dst)[kRows], std::int16_t (&masks)[4][2 * kRows]) {
  const int n = std::min(kRows, height - y0);
  for (int r = 0; r < n; ++r) {
    const std::uint8_t* row = rows + std::size_t(y0 + r) * stride;
    cur[r] = row + 1;
    dst[r] = out.ptr<std::uint16_t>(y0 + r);
    if (row[0] >= 1 && row[0] <= 4) masks[row[0] - 1][2 * r] = masks[row[0] - 1][2 * r + 1] = -1;
  }
  return n;
}

inline std::uint16_t load_u16(const std::uint8_t* p) {
  std::uint16_t v;
  std::memcpy(&v, p, 2);
  return v;
}

// Step s: row r at pixel s - r. Masked steps leave out the lanes outside their row (band start
// and end, missing rows); their results are zero, which is what "left" and "above-left" of a
// row's first pixel must read.
template <bool kMasked>
inline void band_step(const Band& band, int s, __m128i& res, __m128i& prev_b) {
  const auto valid = [&](int r) { return !kMasked || (r < band.rows && s - r >= 0 && s - r < band.width); };
  __m128i xw = _mm_setzero_si128();
  if (valid(0)) xw = _mm_insert_epi16(xw, load_u16(band.cur[0] + 2 * s), 0);
  if (valid(1)) xw = _mm_insert_epi16(xw, load_u16(band.cur[1] + 2 * (s - 1)), 1);
  if (valid(2)) xw = _mm_insert_epi16(xw, load_u16(band.cur[2] + 2 * (s - 2)), 2);
  if (valid(3)) xw = _mm_insert_epi16(xw, load_u16(band.cur[3] + 2 * (s - 3)), 3);
  const __m128i x = _mm_cvtepu8_epi16(xw);
  const int above = valid(0) ? band.above[s] : 0;
  const __m128i a = res;
  const __m128i b = _mm_or_si128(_mm_slli_si128(res, 4), _mm_cvtsi32_si128((above >> 8) | ((above & 0xff) << 16)));
  const __m128i c = prev_b;
  const __m128i lo = _mm_min_epi16(a, b), hi = _mm_max_epi16(a, b);
  const __m128i t = _mm_sub_epi16(_mm_sub_epi16(_mm_add_epi16(c, _mm_add_epi16(c, c)), a), b);
  const __m128i lo_or_c = _mm_blendv_epi8(lo, c, _mm_cmpgt_epi16(hi, t));
  const __m128i paeth = _mm_blendv_epi8(hi, lo_or_c, _mm_cmpgt_epi16(t, lo));
  const __m128i average = _mm_srli_epi16(_mm_add_epi16(a, b), 1);
  const __m128i pred =
      _mm_or_si128(_mm_or_si128(_mm_and_si128(a, band.sub), _mm_and_si128(b, band.up)),
                   _mm_or_si128(_mm_and_si128(average, band.average), _mm_and_si128(paeth, band.paeth)));
  res = _mm_and_si128(_mm_add_epi16(x, pred), _mm_set1_epi16(0xff));
  if (kMasked)
    res = _mm_and_si128(res, _mm_set_epi16(short(-valid(3)), short(-valid(3)), short(-valid(2)), short(-valid(2)),
                                           short(-valid(1)), short(-valid(1)), short(-valid(0)), short(-valid(0))));
  prev_b = b;
  // 32-bit lane r holds high | low << 16; its low 16 bits become high << 8 | low.
  const __m128i v = _mm_or_si128(_mm_slli_epi32(res, 8), _mm_srli_epi32(res, 16));
  if (valid(0)) band.dst[0][s] = std::uint16_t(_mm_extract_epi16(v, 0));
  if (valid(1)) band.dst[1][s - 1] = std::uint16_t(_mm_extract_epi16(v, 2));
  if (valid(2)) band.dst[2][s - 2] = std::uint16_t(_mm_extract_epi16(v, 4));
  if (valid(3)) band.dst[3][s - 3] = std::uint16_t(_mm_extract_epi16(v, 6));
}

void unfilter_rows_simd(const std::uint8_t* rows, int width, int height, cv::Mat& out) {
  const std::size_t stride = 1 + 2 * std::size_t(width);
  const std::vector<std::uint16_t> zeros(std::size_t(width), 0);
  const std::uint16_t* above = zeros.data();
  for (int y0 = 0; y0 < height; y0 += 4) {
    Band band{};
    std::int16_t masks[4][8] = {};  // sub, up, average, paeth
    band.rows = band_rows(rows, stride, y0, height, out, band.cur, band.dst, masks);
    band.width = width;
    band.above = above;
    band.sub = _mm_loadu_si128(reinterpret_cast<const __m128i*>(masks[0]));
    band.up = _mm_loadu_si128(reinterpret_cast<const __m128i*>(masks[1]));
    band.average = _mm_loadu_si128(reinterpret_cast<const __m128i*>(masks[2]));
    band.paeth = _mm_loadu_si128(reinterpret_cast<const __m128i*>(masks[3]));
    __m128i res = _mm_setzero_si128(), prev_b = _mm_setzero_si128();
    const int steps = width + band.rows - 1;
    int s = 0;
    if (band.rows == 4) {
      for (; s < std::min(3, steps); ++s) band_step<true>(band, s, res, prev_b);
      for (; s < width; ++s) band_step<false>(band, s, res, prev_b);
    }
    for (; s < steps; ++s) band_step<true>(band, s, res, prev_b);
    above = band.dst[band.rows - 1];
  }
}
#endif

#if defined(CSLAM_PNG16_AVX2)
// Eight rows at once, as the SSE4.1 band: row r in 32-bit element r (high byte in its low 16-bit
// lane, low byte in its high one), one pixel behind row r - 1. "Above" is the element below,
// moved up by a rotation of the eight elements (the bands' only lane-crossing step); the
// predictors are the same 16-bit arithmetic on twice the lanes.
struct Band8 {
  const std::uint8_t* cur[8];
  std::uint16_t* dst[8];
  const std::uint16_t* above;
  int rows, width;
  __m256i sub, up, average, paeth;
};

template <bool kMasked>
__attribute__((target("avx2"))) inline void band8_step(const Band8& band, int s, __m256i& res, __m256i& prev_b) {
  const auto valid = [&](int r) { return !kMasked || (r < band.rows && s - r >= 0 && s - r < band.width); };
  __m128i xw = _mm_setzero_si128();
  if (valid(0)) xw = _mm_insert_epi16(xw, load_u16(band.cur[0] + 2 * s), 0);
  if (valid(1)) xw = _mm_insert_epi16(xw, load_u16(band.cur[1] + 2 * (s - 1)), 1);
  if (valid(2)) xw = _mm_insert_epi16(xw, load_u16(band.cur[2] + 2 * (s - 2)), 2);
  if (valid(3)) xw = _mm_insert_epi16(xw, load_u16(band.cur[3] + 2 * (s - 3)), 3);
  if (valid(4)) xw = _mm_insert_epi16(xw, load_u16(band.cur[4] + 2 * (s - 4)), 4);
  if (valid(5)) xw = _mm_insert_epi16(xw, load_u16(band.cur[5] + 2 * (s - 5)), 5);
  if (valid(6)) xw = _mm_insert_epi16(xw, load_u16(band.cur[6] + 2 * (s - 6)), 6);
  if (valid(7)) xw = _mm_insert_epi16(xw, load_u16(band.cur[7] + 2 * (s - 7)), 7);
  const __m256i x = _mm256_cvtepu8_epi16(xw);
  const int above = valid(0) ? band.above[s] : 0;
  const __m256i a = res;
  const __m256i rotated = _mm256_permutevar8x32_epi32(res, _mm256_setr_epi32(7, 0, 1, 2, 3, 4, 5, 6));
  const __m256i b =
      _mm256_blend_epi32(rotated, _mm256_castsi128_si256(_mm_cvtsi32_si128((above >> 8) | ((above & 0xff) << 16))), 1);
  const __m256i c = prev_b;
  const __m256i lo = _mm256_min_epi16(a, b), hi = _mm256_max_epi16(a, b);
  const __m256i t = _mm256_sub_epi16(_mm256_sub_epi16(_mm256_add_epi16(c, _mm256_add_epi16(c, c)), a), b);
  const __m256i lo_or_c = _mm256_blendv_epi8(lo, c, _mm256_cmpgt_epi16(hi, t));
  const __m256i paeth = _mm256_blendv_epi8(hi, lo_or_c, _mm256_cmpgt_epi16(t, lo));
  const __m256i average = _mm256_srli_epi16(_mm256_add_epi16(a, b), 1);
  const __m256i pred =
      _mm256_or_si256(_mm256_or_si256(_mm256_and_si256(a, band.sub), _mm256_and_si256(b, band.up)),
                      _mm256_or_si256(_mm256_and_si256(average, band.average), _mm256_and_si256(paeth, band.paeth)));
  res = _mm256_and_si256(_mm256_add_epi16(x, pred), _mm256_set1_epi16(0xff));
  if (kMasked)
    res = _mm256_and_si256(res, _mm256_setr_epi32(-int(valid(0)), -int(valid(1)), -int(valid(2)), -int(valid(3)),
                                                  -int(valid(4)), -int(valid(5)), -int(valid(6)), -int(valid(7))));
  prev_b = b;
  alignas(32) std::uint32_t v[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(v),
                     _mm256_or_si256(_mm256_slli_epi32(res, 8), _mm256_srli_epi32(res, 16)));
  for (int r = 0; r < 8; ++r)
    if (valid(r)) band.dst[r][s - r] = std::uint16_t(v[r]);
}

__attribute__((target("avx2"))) void unfilter_rows_avx2(const std::uint8_t* rows, int width, int height, cv::Mat& out) {
  const std::size_t stride = 1 + 2 * std::size_t(width);
  const std::vector<std::uint16_t> zeros(std::size_t(width), 0);
  const std::uint16_t* above = zeros.data();
  for (int y0 = 0; y0 < height; y0 += 8) {
    Band8 band{};
    std::int16_t masks[4][16] = {};  // sub, up, average, paeth
    band.rows = band_rows(rows, stride, y0, height, out, band.cur, band.dst, masks);
    band.width = width;
    band.above = above;
    band.sub = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(masks[0]));
    band.up = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(masks[1]));
    band.average = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(masks[2]));
    band.paeth = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(masks[3]));
    __m256i res = _mm256_setzero_si256(), prev_b = _mm256_setzero_si256();
    const int steps = width + band.rows - 1;
    int s = 0;
    if (band.rows == 8) {
      for (; s < std::min(7, steps); ++s) band8_step<true>(band, s, res, prev_b);
      for (; s < width; ++s) band8_step<false>(band, s, res, prev_b);
    }
    for (; s < steps; ++s) band8_step<true>(band, s, res, prev_b);
    above = band.dst[band.rows - 1];
  }
}
#endif

}  // namespace

namespace png16_detail {

UnfilterPath unfilter_best_path() {
#if defined(CSLAM_PNG16_AVX2)
  if (cpu_has_avx2()) return UnfilterPath::kAvx2;
#endif
#if defined(__SSE4_1__)
  return UnfilterPath::kSse41;
#else
  return UnfilterPath::kScalar;
#endif
}

void unfilter_rows(std::uint8_t* rows, int width, int height, cv::Mat& out, UnfilterPath path) {
#if defined(CSLAM_PNG16_AVX2)
  if (path == UnfilterPath::kAvx2 && cpu_has_avx2()) return unfilter_rows_avx2(rows, width, height, out);
#endif
#if defined(__SSE4_1__)
  if (path != UnfilterPath::kScalar) return unfilter_rows_simd(rows, width, height, out);
#endif
  unfilter_rows_scalar(rows, width, height, out);
}

}  // namespace png16_detail

bool decode_png16_gray(const std::uint8_t* d, std::size_t size, cv::Mat& out, std::string* why) {
  static const png_detail::PngFormat kFormat = {16, 0, 2, "16-bit greyscale"};
  png_detail::InflatedPng png;  // declared first: releases oversized scratch on every way out
  if (!png_detail::inflate_png(d, size, kFormat, png, why)) return false;
  cv::Mat image(png.height, png.width, CV_16UC1);
  png16_detail::unfilter_rows(png.rows, png.width, png.height, image, png16_detail::unfilter_best_path());
  out = image;
  return true;
}

}  // namespace cslam
