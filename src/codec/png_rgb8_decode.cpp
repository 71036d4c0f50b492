#include "codec/png_rgb8_decode.h"

#include <algorithm>
#include <cstring>
#include <vector>

#include "codec/png_inflate.h"

#if defined(__SSE4_1__)
#include <smmintrin.h>
#endif

namespace cslam {

namespace {

// Every PNG filter works per channel: a byte's "left" neighbour is the same channel of the pixel
// before (3 bytes back), "above" the same byte of the row above. So the filters can be undone in
// BGR order as well as in RGB order: both kernels swap R and B as they read the filtered bytes,
// write straight into the output and read the row above from there (no second pass).

// Scalar, pixel by pixel; the three channels are independent chains. The fallback without
// SSE4.1 and the tests' second opinion on the vector kernel.
void unfilter_row_scalar(int filter, const std::uint8_t* __restrict in, const std::uint8_t* __restrict prev,
                         std::uint8_t* __restrict out, int width) {
  const std::size_t n = 3 * std::size_t(width);
  switch (filter) {
    case 0:
      for (std::size_t i = 0; i < n; i += 3) {
        out[i] = in[i + 2];
        out[i + 1] = in[i + 1];
        out[i + 2] = in[i];
      }
      break;
    case 1: {
      std::uint8_t b = 0, g = 0, r = 0;
      for (std::size_t i = 0; i < n; i += 3) {
        b = std::uint8_t(in[i + 2] + b);
        g = std::uint8_t(in[i + 1] + g);
        r = std::uint8_t(in[i] + r);
        out[i] = b;
        out[i + 1] = g;
        out[i + 2] = r;
      }
      break;
    }
    case 2:
      for (std::size_t i = 0; i < n; i += 3) {
        out[i] = std::uint8_t(in[i + 2] + prev[i]);
        out[i + 1] = std::uint8_t(in[i + 1] + prev[i + 1]);
        out[i + 2] = std::uint8_t(in[i] + prev[i + 2]);
      }
      break;
    case 3: {
      int b = 0, g = 0, r = 0;
      for (std::size_t i = 0; i < n; i += 3) {
        b = std::uint8_t(in[i + 2] + ((b + prev[i]) >> 1));
        g = std::uint8_t(in[i + 1] + ((g + prev[i + 1]) >> 1));
        r = std::uint8_t(in[i] + ((r + prev[i + 2]) >> 1));
        out[i] = std::uint8_t(b);
        out[i + 1] = std::uint8_t(g);
        out[i + 2] = std::uint8_t(r);
      }
      break;
    }
    case 4: {
      // Left and above-left start at zero: the first pixel's predictor is then the byte above.
      int b = 0, g = 0, r = 0, cb = 0, cg = 0, cr = 0;
      for (std::size_t i = 0; i < n; i += 3) {
        const int ub = prev[i], ug = prev[i + 1], ur = prev[i + 2];
        b = std::uint8_t(in[i + 2] + png_detail::paeth(b, ub, cb));
        g = std::uint8_t(in[i + 1] + png_detail::paeth(g, ug, cg));
        r = std::uint8_t(in[i] + png_detail::paeth(r, ur, cr));
        out[i] = std::uint8_t(b);
        out[i + 1] = std::uint8_t(g);
        out[i + 2] = std::uint8_t(r);
        cb = ub, cg = ug, cr = ur;
      }
      break;
    }
    default:
      break;
  }
}

void unfilter_rows_scalar(const std::uint8_t* rows, int width, int height, cv::Mat& out) {
  const std::size_t stride = 1 + 3 * std::size_t(width);
  const std::vector<std::uint8_t> zeros(3 * std::size_t(width), 0);
  const std::uint8_t* prev = zeros.data();
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* row = rows + std::size_t(y) * stride;
    std::uint8_t* dst = out.ptr<std::uint8_t>(y);
    unfilter_row_scalar(row[0], row + 1, prev, dst, width);
    prev = dst;
  }
}

#if defined(__SSE4_1__)
// Eight rows at once, as png16_decode.cpp does four for 16-bit pixels, here with byte lanes in two
// registers: row r of a band sits in bytes 4(r % 4)..4(r % 4) + 2 of register r / 4 (B, G, R; the
// fourth byte is unused) and runs one pixel behind row r - 1, so its bytes "above" and
// "above-left" are row r - 1's results of the previous two steps (a 4-byte shift across the
// registers, no memory) and 24 byte chains advance together. Each lane computes every predictor
// and keeps its row's: one kernel for all filters. Byte arithmetic is exactly the filters'
// (modular, no widening); only Paeth needs care, see paeth_u8. Row 0 reads the row above the band
// from the output. The two registers' chains are independent within a step, which hides some of
// their latency: per 640x480 image of mostly Paeth rows 0.49 ms with four rows (one register),
// 0.34 with eight (three registers: 0.37), the scalar loops 1.55.
constexpr int kGroups = 2;  // registers per band
constexpr int kBandRows = 4 * kGroups;

struct Band {
  const std::uint8_t* cur[kBandRows];  // filtered bytes (RGB) of the band's rows
  std::uint8_t* dst[kBandRows];        // their output rows (BGR)
  const std::uint8_t* above;           // the decoded row above the band
  int rows, width;
  __m128i sub[kGroups], up[kGroups], average[kGroups], paeth[kGroups];  // per-lane masks of the rows' filters
};

// Unmasked steps keep every row's pixel before its row's last, so 4-byte loads and stores stay
// inside the rows: the 4th byte stored is the next pixel's first, written over in the next step.
// Masked steps (band start and end) move exactly 3 bytes.
template <bool kMasked>
inline std::uint32_t load_pixel(const std::uint8_t* p) {
  std::uint32_t v = 0;
  std::memcpy(&v, p, kMasked ? 3 : 4);
  return v;
}

template <bool kMasked>
inline void store_pixel(std::uint8_t* p, std::uint32_t v) {
  std::memcpy(p, &v, kMasked ? 3 : 4);
}

inline __m128i absdiff_u8(__m128i x, __m128i y) { return _mm_sub_epi8(_mm_max_epu8(x, y), _mm_min_epu8(x, y)); }

// x <= y for unsigned bytes, as all-ones / zero lanes.
inline __m128i le_u8(__m128i x, __m128i y) { return _mm_cmpeq_epi8(_mm_min_epu8(x, y), x); }

// The spec's Paeth predictor on unsigned bytes: pa = |b - c| and pb = |a - c| fit in a byte;
// pc = |(b - c) + (a - c)| is their sum when a and b lie on the same side of c, else their
// difference (a side of 0 gives the same either way). The sum may exceed 255: saturating it keeps
// every comparison with pa, pb <= 255 the same. Ties go to a, then b, as in the spec.
inline __m128i paeth_u8(__m128i a, __m128i b, __m128i c) {
  const __m128i max_bc = _mm_max_epu8(b, c), max_ac = _mm_max_epu8(a, c);
  const __m128i pa = _mm_sub_epi8(max_bc, _mm_min_epu8(b, c));
  const __m128i pb = _mm_sub_epi8(max_ac, _mm_min_epu8(a, c));
  const __m128i b_ge_c = _mm_cmpeq_epi8(max_bc, b), a_ge_c = _mm_cmpeq_epi8(max_ac, a);
  const __m128i pc = _mm_blendv_epi8(_mm_adds_epu8(pa, pb), absdiff_u8(pa, pb), _mm_xor_si128(b_ge_c, a_ge_c));
  const __m128i a_wins = _mm_and_si128(le_u8(pa, pb), le_u8(pa, pc));
  return _mm_blendv_epi8(_mm_blendv_epi8(c, b, le_u8(pb, pc)), a, a_wins);
}

// Step s: row r at pixel s - r. Masked steps leave out the rows outside their pixel range (band
// start and end, missing rows); their results are zero, which is what "left" and "above-left"
// of a row's first pixel must read.
template <bool kMasked>
inline void band_step(const Band& band, int s, __m128i (&res)[kGroups], __m128i (&prev_b)[kGroups]) {
  const auto valid = [&](int r) { return !kMasked || (r < band.rows && s - r >= 0 && s - r < band.width); };
  const auto load = [&](int r) { return valid(r) ? int(load_pixel<kMasked>(band.cur[r] + 3 * (s - r))) : 0; };
  const auto store = [&](int r, int v) {
    if (valid(r)) store_pixel<kMasked>(band.dst[r] + 3 * (s - r), std::uint32_t(v));
  };
  // "Above" from the previous step's results, one row up; the band's first row reads the output.
  __m128i b[kGroups];
  const std::uint32_t above = valid(0) ? load_pixel<kMasked>(band.above + 3 * s) : 0;
  b[0] = _mm_or_si128(_mm_slli_si128(res[0], 4), _mm_cvtsi32_si128(int(above)));
  // Unrolled, also at -O2: the registers must not go through memory.
#pragma GCC unroll 4
  for (int g = 1; g < kGroups; ++g) b[g] = _mm_alignr_epi8(res[g], res[g - 1], 12);
#pragma GCC unroll 4
  for (int g = 0; g < kGroups; ++g) {
    const int r = 4 * g;
    const __m128i xw = _mm_setr_epi32(load(r), load(r + 1), load(r + 2), load(r + 3));
    // RGB -> BGR, and the unused byte of each pixel to zero.
    const __m128i x = _mm_shuffle_epi8(xw, _mm_setr_epi8(2, 1, 0, -1, 6, 5, 4, -1, 10, 9, 8, -1, 14, 13, 12, -1));
    const __m128i a = res[g], c = prev_b[g];
    const __m128i average =
        _mm_sub_epi8(_mm_avg_epu8(a, b[g]), _mm_and_si128(_mm_xor_si128(a, b[g]), _mm_set1_epi8(1)));  // floor
    const __m128i paeth = paeth_u8(a, b[g], c);
    const __m128i pred =
        _mm_or_si128(_mm_or_si128(_mm_and_si128(a, band.sub[g]), _mm_and_si128(b[g], band.up[g])),
                     _mm_or_si128(_mm_and_si128(average, band.average[g]), _mm_and_si128(paeth, band.paeth[g])));
    res[g] = _mm_add_epi8(x, pred);
    if (kMasked) {
      const __m128i keep = _mm_setr_epi32(-int(valid(r)), -int(valid(r + 1)), -int(valid(r + 2)), -int(valid(r + 3)));
      res[g] = _mm_and_si128(res[g], keep);
    }
    prev_b[g] = b[g];
    store(r, _mm_cvtsi128_si32(res[g]));
    store(r + 1, _mm_extract_epi32(res[g], 1));
    store(r + 2, _mm_extract_epi32(res[g], 2));
    store(r + 3, _mm_extract_epi32(res[g], 3));
  }
}

void unfilter_rows_simd(const std::uint8_t* rows, int width, int height, cv::Mat& out) {
  const std::size_t stride = 1 + 3 * std::size_t(width);
  const std::vector<std::uint8_t> zeros(3 * std::size_t(width), 0);
  const std::uint8_t* above = zeros.data();
  for (int y0 = 0; y0 < height; y0 += kBandRows) {
    Band band{};
    band.rows = std::min(kBandRows, height - y0);
    band.width = width;
    band.above = above;
    std::int32_t masks[4][kBandRows] = {};  // sub, up, average, paeth; one 32-bit lane per row
    bool any_slow = false;                  // a row with the Average or Paeth filter
    for (int r = 0; r < band.rows; ++r) {
      const std::uint8_t* row = rows + std::size_t(y0 + r) * stride;
      band.cur[r] = row + 1;
      band.dst[r] = out.ptr<std::uint8_t>(y0 + r);
      if (row[0] >= 1 && row[0] <= 4) masks[row[0] - 1][r] = -1;
      any_slow = any_slow || row[0] >= 3;
    }
    if (!any_slow) {
      // None, Sub and Up only (all rows of OpenCV's default PNGs are Sub): the scalar loops have
      // short chains and nothing to select, 0.22 instead of 0.35 ms for a 640x480 image.
      for (int r = 0; r < band.rows; ++r) {
        unfilter_row_scalar(band.cur[r][-1], band.cur[r], above, band.dst[r], width);
        above = band.dst[r];
      }
      continue;
    }
    const auto mask = [&](int type, int g) {
      return _mm_loadu_si128(reinterpret_cast<const __m128i*>(masks[type] + 4 * g));
    };
    __m128i res[kGroups], prev_b[kGroups];
    for (int g = 0; g < kGroups; ++g) {
      band.sub[g] = mask(0, g);
      band.up[g] = mask(1, g);
      band.average[g] = mask(2, g);
      band.paeth[g] = mask(3, g);
      res[g] = prev_b[g] = _mm_setzero_si128();
    }
    const int steps = width + band.rows - 1;
    int s = 0;
    if (band.rows == kBandRows) {
      for (; s < std::min(kBandRows - 1, steps); ++s) band_step<true>(band, s, res, prev_b);
      for (; s < width - 1; ++s) band_step<false>(band, s, res, prev_b);
    }
    for (; s < steps; ++s) band_step<true>(band, s, res, prev_b);
    above = band.dst[band.rows - 1];
  }
}
#endif

}  // namespace

namespace png_rgb8_detail {

void unfilter_rows(const std::uint8_t* rows, int width, int height, cv::Mat& out, bool simd) {
#if defined(__SSE4_1__)
  if (simd) return unfilter_rows_simd(rows, width, height, out);
#endif
  unfilter_rows_scalar(rows, width, height, out);
}

void paeth_predict(const std::uint8_t* a, const std::uint8_t* b, const std::uint8_t* c, std::uint8_t* out,
                   std::size_t n) {
  std::size_t i = 0;
#if defined(__SSE4_1__)
  const auto load = [](const std::uint8_t* p) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p)); };
  for (; i + 16 <= n; i += 16)
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i), paeth_u8(load(a + i), load(b + i), load(c + i)));
#endif
  for (; i < n; ++i) out[i] = std::uint8_t(png_detail::paeth(a[i], b[i], c[i]));
}

}  // namespace png_rgb8_detail

bool decode_png_rgb8(const std::uint8_t* d, std::size_t size, cv::Mat& out, std::string* why) {
  static const png_detail::PngFormat kFormat = {8, 2, 3, "8-bit RGB"};
  png_detail::InflatedPng png;  // declared first: releases oversized scratch on every way out
  if (!png_detail::inflate_png(d, size, kFormat, png, why)) return false;
  cv::Mat image(png.height, png.width, CV_8UC3);
  png_rgb8_detail::unfilter_rows(png.rows, png.width, png.height, image, true);
  out = image;
  return true;
}

}  // namespace cslam
