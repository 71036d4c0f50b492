#include "slam/features/linear_resize.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <vector>

#include <opencv2/imgproc.hpp>

#if defined(__SSSE3__)
#include <tmmintrin.h>
#endif

namespace cslam {

namespace {

constexpr int kCoefScale = 2048;  // OpenCV's INTER_RESIZE_COEF_SCALE (11 bits)

// Source index and fixed-point weights of each destination index along one axis, as OpenCV
// computes them: the position in double, rounded to float, its floor and fraction; the weights
// 1 - f and f rounded to nearest (even) in 11 bits. Positions before the first pixel are
// clamped to it; from the first position whose right neighbour lies outside (`last_pair`), the
// pixel is taken alone.
struct AxisTable {
  std::vector<int> index;
  std::vector<std::int16_t> w0, w1;
  int last_pair = 0;  // entries [0, last_pair) blend index and index + 1
  // The horizontal pass in blocks of four destination pixels whose source pairs lie within 16
  // bytes from the block's first: per block, a byte shuffle that spreads those pairs into 16-bit
  // lanes and the four weight pairs, for one multiply-add. Blocks [0, blocks); the rest pixel by pixel.
  int blocks = 0;
  std::vector<std::uint8_t> shuffle;  // 16 per block
  std::vector<std::int16_t> weights;  // 8 per block: w0, w1 of each pixel
};

void add_blocks(AxisTable& t, int src_size) {
  for (int b = 0; 4 * b + 3 < t.last_pair; ++b) {
    const int first = t.index[std::size_t(4 * b)];
    if (first + 16 > src_size || t.index[std::size_t(4 * b + 3)] + 1 - first > 15) break;
    for (int k = 0; k < 4; ++k) {
      const std::size_t d = std::size_t(4 * b + k);
      const auto offset = std::uint8_t(t.index[d] - first);
      t.shuffle.insert(t.shuffle.end(), {offset, 0x80, std::uint8_t(offset + 1), 0x80});
      t.weights.insert(t.weights.end(), {t.w0[d], t.w1[d]});
    }
    t.blocks = b + 1;
  }
}

AxisTable axis_table(int src_size, int dst_size) {
  AxisTable t;
  t.index.resize(std::size_t(dst_size));
  t.w0.resize(std::size_t(dst_size));
  t.w1.resize(std::size_t(dst_size));
  t.last_pair = dst_size;
  const double scale = 1.0 / (double(dst_size) / src_size);
  for (int d = 0; d < dst_size; ++d) {
    float f = float((d + 0.5) * scale - 0.5);
    int s = int(std::floor(f));
    f -= float(s);
    if (s < 0) f = 0, s = 0;
    if (s + 1 >= src_size) {
      t.last_pair = std::min(t.last_pair, d);
      if (s >= src_size - 1) f = 0, s = src_size - 1;
    }
    t.index[std::size_t(d)] = s;
    const auto round16 = [](float v) {
      return std::int16_t(std::clamp(long(std::lrintf(v)), long(INT16_MIN), long(INT16_MAX)));
    };
    t.w0[std::size_t(d)] = round16((1.f - f) * kCoefScale);
    t.w1[std::size_t(d)] = round16(f * kCoefScale);
  }
  return t;
}

void horizontal(const std::uint8_t* s, const AxisTable& x, int width, std::int32_t* out) {
  // Local copies of the tables' pointers: stores into `out` would otherwise reload them.
  const int* index = x.index.data();
  const std::int16_t *w0 = x.w0.data(), *w1 = x.w1.data();
  const int blocks = x.blocks, last_pair = x.last_pair;
  int d = 0;
#if defined(__SSSE3__)
  const std::uint8_t* shuffle = x.shuffle.data();
  const std::int16_t* weights = x.weights.data();
  for (int b = 0; b < blocks; ++b, d += 4) {
    const __m128i pixels = _mm_loadu_si128(reinterpret_cast<const __m128i*>(s + index[d]));
    const __m128i spread =
        _mm_shuffle_epi8(pixels, _mm_loadu_si128(reinterpret_cast<const __m128i*>(shuffle + 16 * b)));
    const __m128i w = _mm_loadu_si128(reinterpret_cast<const __m128i*>(weights + 8 * b));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + d), _mm_madd_epi16(spread, w));
  }
#endif
  for (; d < last_pair; ++d) out[d] = s[index[d]] * w0[d] + s[index[d] + 1] * w1[d];
  for (; d < width; ++d) out[d] = s[index[d]] * kCoefScale;
}

// OpenCV's vector rounding for columns [0, end).
void vertical_vector(const std::int32_t* r0, const std::int32_t* r1, int b0, int b1, int end, std::uint8_t* out) {
  int x = 0;
#if defined(__SSSE3__)
  const __m128i vb0 = _mm_set1_epi16(std::int16_t(b0)), vb1 = _mm_set1_epi16(std::int16_t(b1));
  const __m128i two = _mm_set1_epi16(2);
  for (; x + 8 <= end; x += 8) {
    const auto load = [](const std::int32_t* p) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p)); };
    const __m128i s0 = _mm_packs_epi32(_mm_srai_epi32(load(r0 + x), 4), _mm_srai_epi32(load(r0 + x + 4), 4));
    const __m128i s1 = _mm_packs_epi32(_mm_srai_epi32(load(r1 + x), 4), _mm_srai_epi32(load(r1 + x + 4), 4));
    const __m128i sum = _mm_adds_epi16(_mm_mulhi_epi16(s0, vb0), _mm_mulhi_epi16(s1, vb1));
    const __m128i v = _mm_srai_epi16(_mm_adds_epi16(sum, two), 2);
    _mm_storel_epi64(reinterpret_cast<__m128i*>(out + x), _mm_packus_epi16(v, v));
  }
#endif
  const auto sat16 = [](int v) { return std::clamp(v, int(INT16_MIN), int(INT16_MAX)); };
  for (; x < end; ++x) {
    const int s0 = sat16(r0[x] >> 4), s1 = sat16(r1[x] >> 4);
    const int sum = sat16(((s0 * b0) >> 16) + ((s1 * b1) >> 16));
    out[x] = std::uint8_t(std::clamp(sat16(sum + 2) >> 2, 0, 255));
  }
}

// OpenCV's scalar rounding for columns [begin, end).
void vertical_scalar(const std::int32_t* r0, const std::int32_t* r1, int b0, int b1, int begin, int end,
                     std::uint8_t* out) {
  for (int x = begin; x < end; ++x)
    out[x] = std::uint8_t(std::clamp((r0[x] * b0 + r1[x] * b1 + (1 << 21)) >> 22, 0, 255));
}

}  // namespace

void resize_linear(const cv::Mat& source, cv::Mat& dst, cv::Size size, const LinearResize& rule) {
  const cv::Mat src = source;  // holds the pixels if dst is the same matrix (create() reallocates it)
  if (src.type() != CV_8UC1) throw std::invalid_argument("resize_linear: image must be CV_8UC1");
  if (src.empty() || size.width < 1 || size.height < 1) throw std::invalid_argument("resize_linear: empty size");
  if (size.width > src.cols || size.height > src.rows)
    throw std::invalid_argument("resize_linear: downscaling only (cv::resize enlarges by another path)");
  AxisTable xs = axis_table(src.cols, size.width);
  const AxisTable ys = axis_table(src.rows, size.height);
  add_blocks(xs, src.cols);
  dst.create(size, CV_8UC1);
  const int W = size.width;
  const int vector_end = rule.vector_columns > 0 ? W / rule.vector_columns * rule.vector_columns : 0;
  // Two horizontal rows, each remembered by its source row.
  std::vector<std::int32_t> buffer(2 * std::size_t(W));
  std::int32_t* rows[2] = {buffer.data(), buffer.data() + W};
  int row_of[2] = {-1, -1};
  const auto row = [&](int y) -> const std::int32_t* {
    for (int k = 0; k < 2; ++k)
      if (row_of[k] == y) return rows[k];
    // Source rows only grow from one output row to the next, so the slot of the smaller row is
    // free: the row this output row needs besides `y` is the larger one or `y` itself.
    const int k = row_of[0] < row_of[1] ? 0 : 1;
    horizontal(src.ptr<std::uint8_t>(y), xs, W, rows[k]);
    row_of[k] = y;
    return rows[k];
  };
  for (int dy = 0; dy < size.height; ++dy) {
    const int s = ys.index[std::size_t(dy)];
    const int y0 = std::min(s, src.rows - 1), y1 = std::min(s + 1, src.rows - 1);
    const std::int32_t* r0 = row(y0);
    const std::int32_t* r1 = row(y1);
    const int b0 = ys.w0[std::size_t(dy)], b1 = ys.w1[std::size_t(dy)];
    std::uint8_t* out = dst.ptr<std::uint8_t>(dy);
    vertical_vector(r0, r1, b0, b1, vector_end, out);
    vertical_scalar(r0, r1, b0, b1, vector_end, W, out);
  }
}

std::unique_ptr<LinearResize> probe_opencv_linear_resize() {
  // Noise images (every rounding case occurs) at the ORB pyramid's sizes and random smaller ones,
  // downscaled, compared with cv::resize under each candidate rule.
  std::mt19937 rng(7);
  std::vector<std::pair<cv::Size, cv::Size>> cases;
  cv::Size s(640, 480);
  for (int l = 0; l < 8; ++l) {
    const cv::Size next(int(std::lround(s.width / 1.2)), int(std::lround(s.height / 1.2)));
    cases.emplace_back(s, next);
    s = next;
  }
  for (int k = 0; k < 24; ++k) {
    std::uniform_int_distribution<int> side(1, 90);
    const cv::Size from(side(rng), side(rng));
    cases.emplace_back(from, cv::Size(1 + side(rng) % from.width, 1 + side(rng) % from.height));
  }
  std::vector<cv::Mat> images, expected;
  cv::RNG noise(7);  // not OpenCV's shared generator: other code may depend on its sequence
  for (const auto& [from, to] : cases) {
    cv::Mat image(from, CV_8UC1), out;
    noise.fill(image, cv::RNG::UNIFORM, 0, 256);
    cv::resize(image, out, to, 0, 0, cv::INTER_LINEAR);
    images.push_back(image);
    expected.push_back(out);
  }
  for (const int lanes : {1, 8, 16, 32, 0}) {
    LinearResize rule{lanes};
    bool same = true;
    for (std::size_t i = 0; i < cases.size() && same; ++i) {
      cv::Mat out;
      resize_linear(images[i], out, cases[i].second, rule);
      same = cv::countNonZero(out != expected[i]) == 0;
    }
    if (same) return std::make_unique<LinearResize>(rule);
  }
  return nullptr;
}

const LinearResize* opencv_linear_resize() {
  static const std::unique_ptr<LinearResize> rule = probe_opencv_linear_resize();
  return rule.get();
}

}  // namespace cslam
