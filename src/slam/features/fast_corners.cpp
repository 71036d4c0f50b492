#include "slam/features/fast_corners.h"

#include <algorithm>
#include <array>
#include <climits>
#include <cstdint>
#include <stdexcept>

#include "core/cpu_features.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define CSLAM_FAST_AVX2 1
#endif

namespace cslam {

namespace {

// The radius-3 circle in circular order; positions 0, 4, 8 and 12 are its four compass points.
constexpr int kCircle[16][2] = {{0, 3},  {1, 3},   {2, 2},   {3, 1},   {3, 0},  {3, -1}, {2, -2}, {1, -3},
                                {0, -3}, {-1, -3}, {-2, -2}, {-3, -1}, {-3, 0}, {-3, 1}, {-2, 2}, {-1, 3}};

struct Circle {
  std::ptrdiff_t offset[16];
  explicit Circle(std::ptrdiff_t step) {
    for (int k = 0; k < 16; ++k) offset[k] = kCircle[k][0] + kCircle[k][1] * step;
  }
};

int score_at(const std::uint8_t* p, const Circle& circle) {
  const int v = p[0];
  int d[16];
  for (int k = 0; k < 16; ++k) d[k] = v - p[circle.offset[k]];
  int best = INT_MIN;
  for (int start = 0; start < 16; ++start) {
    int darker = INT_MAX, brighter = INT_MAX;
    for (int j = 0; j < 9; ++j) {
      darker = std::min(darker, d[(start + j) & 15]);
      brighter = std::min(brighter, -d[(start + j) & 15]);
    }
    best = std::max({best, darker, brighter});
  }
  return best - 1;
}

#if defined(__SSE2__)
// Per byte lane: the largest, over the 16 arcs of 9 contiguous positions, of the smallest x along
// the arc.
inline __m128i max_arc_min9(const __m128i x[16]) {
  __m128i m2[16], m4[16];
  for (int k = 0; k < 16; ++k) m2[k] = _mm_min_epu8(x[k], x[(k + 1) & 15]);
  for (int k = 0; k < 16; ++k) m4[k] = _mm_min_epu8(m2[k], m2[(k + 2) & 15]);
  __m128i best = _mm_setzero_si128();
  for (int k = 0; k < 16; ++k) {
    const __m128i m8 = _mm_min_epu8(m4[k], m4[(k + 4) & 15]);
    best = _mm_max_epu8(best, _mm_min_epu8(m8, x[(k + 8) & 15]));
  }
  return best;
}
#endif

#if defined(CSLAM_FAST_AVX2)
__attribute__((target("avx2"))) inline void max_arc_min9_avx2(const __m256i x[16], __m256i& best) {
  __m256i m2[16], m4[16];
  for (int k = 0; k < 16; ++k) m2[k] = _mm256_min_epu8(x[k], x[(k + 1) & 15]);
  for (int k = 0; k < 16; ++k) m4[k] = _mm256_min_epu8(m2[k], m2[(k + 2) & 15]);
  for (int k = 0; k < 16; ++k) {
    const __m256i m8 = _mm256_min_epu8(m4[k], m4[(k + 4) & 15]);
    best = _mm256_max_epu8(best, _mm256_min_epu8(m8, x[(k + 8) & 15]));
  }
}

// The scores of the 32 pixels from column x into scores[x ..] (0: no corner), or nothing when the
// block cannot hold a corner (the caller has zeroed the row).
__attribute__((target("avx2"))) void score_block_avx2(const std::uint8_t* row, int x, const Circle& circle,
                                                      int threshold, std::uint8_t* scores) {
  const __m256i t = _mm256_set1_epi8(char(threshold)), zero = _mm256_setzero_si256();
  const std::uint8_t* p = row + x;
  const __m256i v = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
  __m256i dark[4], bright[4];
  for (int q = 0; q < 4; ++q) {
    const __m256i c = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p + circle.offset[4 * q]));
    dark[q] = _mm256_subs_epu8(_mm256_subs_epu8(v, c), t);
    bright[q] = _mm256_subs_epu8(_mm256_subs_epu8(c, v), t);
  }
  __m256i maybe = zero;
  for (int q = 0; q < 4; ++q) {
    maybe = _mm256_max_epu8(maybe, _mm256_min_epu8(dark[q], dark[(q + 1) & 3]));
    maybe = _mm256_max_epu8(maybe, _mm256_min_epu8(bright[q], bright[(q + 1) & 3]));
  }
  if (unsigned(_mm256_movemask_epi8(_mm256_cmpeq_epi8(maybe, zero))) == 0xffffffffu) return;
  __m256i darker[16], brighter[16];
  for (int k = 0; k < 16; ++k) {
    const __m256i c = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p + circle.offset[k]));
    darker[k] = _mm256_subs_epu8(v, c);
    brighter[k] = _mm256_subs_epu8(c, v);
  }
  __m256i s = zero;  // the larger of the two sides' arc maxima
  max_arc_min9_avx2(darker, s);
  max_arc_min9_avx2(brighter, s);
  const __m256i corner = _mm256_xor_si256(_mm256_cmpeq_epi8(_mm256_subs_epu8(s, t), zero), _mm256_set1_epi8(-1));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(scores + x),
                      _mm256_and_si256(_mm256_sub_epi8(s, _mm256_set1_epi8(1)), corner));
}
#endif

#if defined(__SSE2__)
// As score_block_avx2, 16 pixels: the scores of p[0 .. 15] into out[0 .. 15].
void score16_sse2(const std::uint8_t* p, const Circle& circle, int threshold, std::uint8_t* out) {
  // Saturating differences: with s the arc maximum over both sides, the score is s - 1 wherever
  // s > threshold, and a side whose differences are not all positive along an arc contributes 0
  // there instead of a negative value, which only matters below the threshold.
  const __m128i t = _mm_set1_epi8(char(threshold)), zero = _mm_setzero_si128();
  const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p));
  auto at = [&](int k) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + circle.offset[k])); };
  // Any 9 contiguous circle pixels include two neighbouring compass points: a lane with no such
  // pair beyond the threshold on one side holds no corner.
  __m128i dark[4], bright[4];
  for (int q = 0; q < 4; ++q) {
    const __m128i c = at(4 * q);
    dark[q] = _mm_subs_epu8(_mm_subs_epu8(v, c), t);  // non-zero: darker by more than t
    bright[q] = _mm_subs_epu8(_mm_subs_epu8(c, v), t);
  }
  __m128i maybe = zero;
  for (int q = 0; q < 4; ++q) {
    maybe = _mm_max_epu8(maybe, _mm_min_epu8(dark[q], dark[(q + 1) & 3]));
    maybe = _mm_max_epu8(maybe, _mm_min_epu8(bright[q], bright[(q + 1) & 3]));
  }
  if (_mm_movemask_epi8(_mm_cmpeq_epi8(maybe, zero)) == 0xffff) return;
  __m128i darker[16], brighter[16];
  for (int k = 0; k < 16; ++k) {
    const __m128i c = at(k);
    darker[k] = _mm_subs_epu8(v, c);
    brighter[k] = _mm_subs_epu8(c, v);
  }
  const __m128i s = _mm_max_epu8(max_arc_min9(darker), max_arc_min9(brighter));
  const __m128i corner = _mm_xor_si128(_mm_cmpeq_epi8(_mm_subs_epu8(s, t), zero), _mm_set1_epi8(-1));
  _mm_storeu_si128(reinterpret_cast<__m128i*>(out), _mm_and_si128(_mm_sub_epi8(s, _mm_set1_epi8(1)), corner));
}
#endif

// Scores of row y's pixels into `scores` (0 where no corner; the caller has zeroed the row).
void score_row(const cv::Mat& image, int y, const Circle& circle, int threshold, FastCornersPath path,
               std::uint8_t* scores) {
  const std::uint8_t* row = image.ptr<std::uint8_t>(y);
  const int end = image.cols - 3;
  int x = 3;
  // Whole blocks, then one block ending at the last column, overlapping done ones (whose scores
  // come out the same); pixel by pixel only rows narrower than a block.
#if defined(CSLAM_FAST_AVX2)
  if (path == FastCornersPath::kAvx2 && end - x >= 32) {
    for (; x + 32 <= end; x += 32) score_block_avx2(row, x, circle, threshold, scores);
    if (x < end) score_block_avx2(row, end - 32, circle, threshold, scores);
    return;
  }
#endif
#if defined(__SSE2__)
  if (path != FastCornersPath::kScalar && end - x >= 16) {
    for (; x + 16 <= end; x += 16) score16_sse2(row + x, circle, threshold, scores + x);
    if (x < end) score16_sse2(row + end - 16, circle, threshold, scores + end - 16);
    return;
  }
#endif
  for (; x < end; ++x) {
    const int s = score_at(row + x, circle);
    if (s >= threshold) scores[x] = std::uint8_t(s);
  }
}

// Appends row y's corners that score above all eight neighbours (rows above, cur, below; padded
// with zeros to at least width + 16) in column order.
void suppress_row(const std::uint8_t* above, const std::uint8_t* cur, const std::uint8_t* below, int width, int y,
                  bool vector, std::vector<cv::KeyPoint>& keypoints) {
  const int end = width - 3;
  auto emit = [&](int x) { keypoints.emplace_back(float(x), float(y), 7.f, -1.f, float(cur[x])); };
#if defined(__SSE2__)
  if (vector) {
    for (int x = 3; x < end; x += 16) {
      auto at = [&](const std::uint8_t* r, int dx) {
        return _mm_loadu_si128(reinterpret_cast<const __m128i*>(r + x + dx));
      };
      __m128i m = _mm_max_epu8(_mm_max_epu8(at(above, -1), at(above, 0)), _mm_max_epu8(at(above, 1), at(cur, -1)));
      m = _mm_max_epu8(m,
                       _mm_max_epu8(_mm_max_epu8(at(cur, 1), at(below, -1)), _mm_max_epu8(at(below, 0), at(below, 1))));
      // cur > every neighbour (so cur > 0: a corner); lanes past the last column dropped.
      const __m128i above_all = _mm_cmpeq_epi8(_mm_subs_epu8(at(cur, 0), m), _mm_setzero_si128());
      unsigned bits = ~unsigned(_mm_movemask_epi8(above_all)) & 0xffffu;
      if (end - x < 16) bits &= (1u << (end - x)) - 1;
      for (; bits; bits &= bits - 1) emit(x + __builtin_ctz(bits));
    }
    return;
  }
#endif
  for (int x = 3; x < end; ++x) {
    const int s = cur[x];
    if (s > above[x - 1] && s > above[x] && s > above[x + 1] && s > cur[x - 1] && s > cur[x + 1] && s > below[x - 1] &&
        s > below[x] && s > below[x + 1])
      emit(x);
  }
  (void)vector;
}

}  // namespace

int fast_corner_score(const cv::Mat& image, int x, int y) {
  if (image.type() != CV_8UC1) throw std::invalid_argument("fast_corner_score: image must be CV_8UC1");
  if (x < 3 || y < 3 || x >= image.cols - 3 || y >= image.rows - 3)
    throw std::invalid_argument("fast_corner_score: pixel closer than 3 to the border");
  return score_at(image.ptr<std::uint8_t>(y) + x, Circle(std::ptrdiff_t(image.step[0])));
}

std::array<int, 4> fast_neighbour_scores(const cv::Mat& image, int x, int y) {
  if (image.type() != CV_8UC1) throw std::invalid_argument("fast_neighbour_scores: image must be CV_8UC1");
  if (x < 4 || y < 4 || x >= image.cols - 4 || y >= image.rows - 4)
    throw std::invalid_argument("fast_neighbour_scores: pixel closer than 4 to the border");
  const Circle circle(std::ptrdiff_t(image.step[0]));
#if defined(__SSE2__)
  // Threshold 0: a block's score is max(0, the plain score), as below. The reads of a block at
  // x - 1 reach x + 17, so blocks run only that far inside the image.
  if (x + 18 < image.cols) {
    alignas(16) std::uint8_t row[16] = {}, up[16] = {}, down[16] = {};
    score16_sse2(image.ptr<std::uint8_t>(y) + x - 1, circle, 0, row);
    score16_sse2(image.ptr<std::uint8_t>(y - 1) + x, circle, 0, up);
    score16_sse2(image.ptr<std::uint8_t>(y + 1) + x, circle, 0, down);
    return {row[0], row[2], up[0], down[0]};
  }
#endif
  auto score = [&](int xx, int yy) { return std::max(0, score_at(image.ptr<std::uint8_t>(yy) + xx, circle)); };
  return {score(x - 1, y), score(x + 1, y), score(x, y - 1), score(x, y + 1)};
}

FastCornersPath fast_corners_best_path() {
#if defined(CSLAM_FAST_AVX2)
  if (cpu_has_avx2()) return FastCornersPath::kAvx2;
#endif
#if defined(__SSE2__)
  return FastCornersPath::kSse2;
#else
  return FastCornersPath::kScalar;
#endif
}

void detect_fast_corners(const cv::Mat& image, int threshold, std::vector<cv::KeyPoint>& keypoints) {
  detect_fast_corners(image, threshold, keypoints, fast_corners_best_path());
}

void detect_fast_corners(const cv::Mat& image, int threshold, std::vector<cv::KeyPoint>& keypoints,
                         FastCornersPath path) {
  keypoints.clear();
  if (image.type() != CV_8UC1) throw std::invalid_argument("detect_fast_corners: image must be CV_8UC1");
  if (path == FastCornersPath::kAvx2 && fast_corners_best_path() != FastCornersPath::kAvx2)
    throw std::invalid_argument("detect_fast_corners: this CPU cannot run the AVX2 path");
  threshold = std::clamp(threshold, 0, 255);
  const int W = image.cols, H = image.rows;
  if (W < 7 || H < 7) return;
  const Circle circle(std::ptrdiff_t(image.step[0]));
  // Scores of three rows (row y in slot y % 3), zero where no corner, padded for the 16-wide
  // suppression reads; rows 0 .. 2 and H - 3 .. H - 1 hold no corner.
  const std::size_t stride = std::size_t(W) + 16;
  std::vector<std::uint8_t> scores(3 * stride, 0);
  auto row_scores = [&](int y) { return scores.data() + std::size_t(y % 3) * stride; };
  // Row y - 1 is suppressed once row y is scored.
  for (int y = 3; y <= H - 3; ++y) {
    std::uint8_t* below = row_scores(y);
    std::fill(below, below + W, std::uint8_t(0));
    if (y <= H - 4) score_row(image, y, circle, threshold, path, below);
    if (y >= 4)
      suppress_row(row_scores(y - 2), row_scores(y - 1), below, W, y - 1, path != FastCornersPath::kScalar, keypoints);
  }
}

}  // namespace cslam
