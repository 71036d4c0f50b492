#include "features/fast_corners.h"

#include <algorithm>
#include <climits>
#include <cstdint>
#include <stdexcept>

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
constexpr int kCircle[16][2] = {{0, 3},  {1, 3},   {2, 2},   {3, 1},   {3, 0},   {3, -1},  {2, -2},  {1, -3},
                                {0, -3}, {-1, -3}, {-2, -2}, {-3, -1}, {-3, 0},  {-3, 1},  {-2, 2},  {-1, 3}};

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

// The 32 pixels from column x (those from x + first_lane on are new: their corners are recorded;
// the scores of the others are rewritten with the same values).
__attribute__((target("avx2"))) void score_block_avx2(const std::uint8_t* row, int x, int first_lane, const Circle& circle,
                                                      int threshold, std::uint8_t* scores, std::vector<int>& columns) {
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
  unsigned bits = unsigned(_mm256_movemask_epi8(corner));
  if (bits == 0) return;
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(scores + x), _mm256_and_si256(_mm256_sub_epi8(s, _mm256_set1_epi8(1)), corner));
  bits &= ~0u << first_lane;
  for (; bits; bits &= bits - 1) columns.push_back(x + __builtin_ctz(bits));
}
#endif

#if defined(__SSE2__)
// As score_block_avx2, 16 pixels.
void score_block_sse2(const std::uint8_t* row, int x, int first_lane, const Circle& circle, int threshold,
                      std::uint8_t* scores, std::vector<int>& columns) {
  // Saturating differences: with s the arc maximum over both sides, the score is s - 1 wherever
  // s > threshold, and a side whose differences are not all positive along an arc contributes 0
  // there instead of a negative value, which only matters below the threshold.
  const __m128i t = _mm_set1_epi8(char(threshold)), zero = _mm_setzero_si128();
  const std::uint8_t* p = row + x;
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
  unsigned bits = unsigned(_mm_movemask_epi8(corner));
  if (bits == 0) return;
  _mm_storeu_si128(reinterpret_cast<__m128i*>(scores + x), _mm_and_si128(_mm_sub_epi8(s, _mm_set1_epi8(1)), corner));
  bits &= ~0u << first_lane;
  for (; bits; bits &= bits - 1) columns.push_back(x + __builtin_ctz(bits));
}
#endif

// Scores of row y's corners into `scores` (zero elsewhere, which the caller has set) and their
// columns, ascending, into `columns`.
void score_row(const cv::Mat& image, int y, const Circle& circle, int threshold, bool avx2, std::uint8_t* scores,
               std::vector<int>& columns) {
  const std::uint8_t* row = image.ptr<std::uint8_t>(y);
  const int end = image.cols - 3;
  int x = 3;
  // Whole blocks, then one block ending at the last column, overlapping the done ones (their
  // scores come out the same); the scalar loop only for rows narrower than a block.
#if defined(CSLAM_FAST_AVX2)
  if (avx2 && end - x >= 32) {
    for (; x + 32 <= end; x += 32) score_block_avx2(row, x, 0, circle, threshold, scores, columns);
    if (x < end) score_block_avx2(row, end - 32, x - (end - 32), circle, threshold, scores, columns);
    return;
  }
#else
  (void)avx2;
#endif
#if defined(__SSE2__)
  if (end - x >= 16) {
    for (; x + 16 <= end; x += 16) score_block_sse2(row, x, 0, circle, threshold, scores, columns);
    if (x < end) score_block_sse2(row, end - 16, x - (end - 16), circle, threshold, scores, columns);
    return;
  }
#endif
  for (; x < end; ++x) {
    const int s = score_at(row + x, circle);
    if (s >= threshold) {
      scores[x] = std::uint8_t(s);
      columns.push_back(x);
    }
  }
}

}  // namespace

int fast_corner_score(const cv::Mat& image, int x, int y) {
  if (image.type() != CV_8UC1) throw std::invalid_argument("fast_corner_score: image must be CV_8UC1");
  if (x < 3 || y < 3 || x >= image.cols - 3 || y >= image.rows - 3)
    throw std::invalid_argument("fast_corner_score: pixel closer than 3 to the border");
  return score_at(image.ptr<std::uint8_t>(y) + x, Circle(std::ptrdiff_t(image.step[0])));
}

void detect_fast_corners(const cv::Mat& image, int threshold, std::vector<cv::KeyPoint>& keypoints) {
  keypoints.clear();
  if (image.type() != CV_8UC1) throw std::invalid_argument("detect_fast_corners: image must be CV_8UC1");
  threshold = std::clamp(threshold, 0, 255);
  const int W = image.cols, H = image.rows;
  if (W < 7 || H < 7) return;
  const Circle circle(std::ptrdiff_t(image.step[0]));
#if defined(CSLAM_FAST_AVX2)
  const bool avx2 = __builtin_cpu_supports("avx2");
#else
  const bool avx2 = false;
#endif
  // Scores of three rows (y % 3), zero where no corner, and their corners' columns.
  std::vector<std::uint8_t> scores(3 * std::size_t(W), 0);
  std::vector<int> columns[3];
  auto row_scores = [&](int y) { return scores.data() + std::size_t(y % 3) * std::size_t(W); };
  // Row y is scored once rows y - 1 and y + 1 are; corners lie in rows 3 .. H - 4.
  for (int y = 3; y <= H - 3; ++y) {
    std::uint8_t* next = row_scores(y);
    std::fill(next, next + W, std::uint8_t(0));
    columns[y % 3].clear();
    if (y <= H - 4) score_row(image, y, circle, threshold, avx2, next, columns[y % 3]);
    if (y == 3) continue;
    const std::uint8_t* above = y >= 5 ? row_scores(y - 2) : nullptr;  // rows before 3: no corners
    const std::uint8_t* cur = row_scores(y - 1);
    for (int x : columns[(y - 1) % 3]) {
      const int s = cur[x];
      const bool above_lower = !above || (s > above[x - 1] && s > above[x] && s > above[x + 1]);
      if (above_lower && s > cur[x - 1] && s > cur[x + 1] && s > next[x - 1] && s > next[x] && s > next[x + 1])
        keypoints.emplace_back(float(x), float(y - 1), 7.f, -1.f, float(s));
    }
  }
}

}  // namespace cslam
