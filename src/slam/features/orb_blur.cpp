#include "slam/features/orb_blur.h"

#include <array>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "core/cpu_features.h"

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define CSLAM_ORB_BLUR_AVX2 1
#endif

namespace cslam {

namespace {

constexpr int kRadius = 3;  // 7 taps

std::array<float, 7> gaussian_kernel() {
  const cv::Mat k = cv::getGaussianKernel(2 * kRadius + 1, 2.0, CV_32F);
  std::array<float, 7> out{};
  for (int i = 0; i < 7; ++i) out[std::size_t(i)] = k.at<float>(i);
  return out;
}

void blur_opencv(const cv::Mat& level, cv::Mat& out) {
  // As cv::ORB: a bordered copy, its inner part blurred in place (a submatrix: OpenCV reads the
  // border's pixels instead of extrapolating).
  cv::Mat bordered;
  cv::copyMakeBorder(level, bordered, kRadius, kRadius, kRadius, kRadius, cv::BORDER_REFLECT_101 + cv::BORDER_ISOLATED);
  cv::Mat inner = bordered(cv::Rect(kRadius, kRadius, level.cols, level.rows));
  cv::GaussianBlur(inner, inner, cv::Size(7, 7), 2, 2, cv::BORDER_REFLECT_101);
  inner.copyTo(out);
}

#if defined(CSLAM_ORB_BLUR_AVX2)
// Row pass of source row `src` (width w) into `dst` (padded width, a multiple of 8): `pad` holds
// the row as floats with its reflected border, zeros past it.
__attribute__((target("avx2,fma"))) void row_pass(const std::uint8_t* src, int w, const std::array<float, 7>& k,
                                                  float* pad, float* dst, int padded) {
  int x = 0;
  for (; x + 8 <= w; x += 8) {
    const __m128i bytes = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(src + x));
    _mm256_storeu_ps(pad + kRadius + x, _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(bytes)));
  }
  for (; x < w; ++x) pad[kRadius + x] = float(src[x]);
  for (int j = 1; j <= kRadius; ++j) {
    pad[kRadius - j] = float(src[j]);
    pad[kRadius + w - 1 + j] = float(src[w - 1 - j]);
  }
  __m256 kv[7];
  for (int j = 0; j < 7; ++j) kv[j] = _mm256_set1_ps(k[std::size_t(j)]);
  // Two independent sums a step: the multiply-adds of one sum form a chain.
  for (x = 0; x < padded; x += 16) {
    const bool second = x + 8 < padded;
    __m256 a = _mm256_mul_ps(kv[0], _mm256_loadu_ps(pad + x));
    __m256 b = _mm256_mul_ps(kv[0], _mm256_loadu_ps(pad + x + 8));
    for (int j = 1; j < 7; ++j) {
      a = _mm256_fmadd_ps(kv[j], _mm256_loadu_ps(pad + x + j), a);
      b = _mm256_fmadd_ps(kv[j], _mm256_loadu_ps(pad + x + 8 + j), b);
    }
    _mm256_storeu_ps(dst + x, a);
    if (second) _mm256_storeu_ps(dst + x + 8, b);
  }
}

// Column pass: output row from the seven row-pass rows r[0 .. 6] (r[3] the centre), 16 pixels a
// step (the rows are padded to a multiple of 8; a last half step reads padding and stores less).
__attribute__((target("avx2,fma"))) __m256i column_sum(const float* const r[7], const __m256 kv[4], int x) {
  __m256 acc = _mm256_mul_ps(kv[0], _mm256_loadu_ps(r[3] + x));
  for (int j = 1; j <= kRadius; ++j)
    acc = _mm256_fmadd_ps(_mm256_add_ps(_mm256_loadu_ps(r[3 + j] + x), _mm256_loadu_ps(r[3 - j] + x)), kv[j], acc);
  return _mm256_cvtps_epi32(acc);  // to nearest, ties to even (the default mode), as cvRound
}

__attribute__((target("avx2,fma"))) void column_pass(const float* const r[7], const std::array<float, 7>& k, int w,
                                                     int padded, std::uint8_t* out) {
  const __m256 kv[4] = {_mm256_set1_ps(k[3]), _mm256_set1_ps(k[4]), _mm256_set1_ps(k[5]), _mm256_set1_ps(k[6])};
  for (int x = 0; x < w; x += 16) {
    const __m256i lo = column_sum(r, kv, x), hi = x + 8 < padded ? column_sum(r, kv, x + 8) : lo;
    // Saturating packs within 128-bit lanes, then the lanes put back in order.
    const __m256i words = _mm256_permute4x64_epi64(_mm256_packs_epi32(lo, hi), 0xd8);
    const __m128i bytes = _mm_packus_epi16(_mm256_castsi256_si128(words), _mm256_extracti128_si256(words, 1));
    if (x + 16 <= w) {
      _mm_storeu_si128(reinterpret_cast<__m128i*>(out + x), bytes);
    } else {
      alignas(16) std::uint8_t tail[16];
      _mm_store_si128(reinterpret_cast<__m128i*>(tail), bytes);
      std::memcpy(out + x, tail, std::size_t(w - x));
    }
  }
}

void blur_avx2(const cv::Mat& level, cv::Mat& out) {
  static const std::array<float, 7> k = gaussian_kernel();  // immutable once made
  const int w = level.cols, h = level.rows;
  const int padded = (w + 7) / 8 * 8;
  // Eight row-pass rows, source row y in slot y % 8: an output row reads seven consecutive ones.
  std::vector<float> pad(std::size_t(padded + 2 * kRadius + 16), 0.f), rows(std::size_t(8) * std::size_t(padded));
  out.create(h, w, CV_8UC1);
  int done = 0;  // source rows passed so far
  const float* r[7];
  for (int y = 0; y < h; ++y) {
    for (; done <= std::min(y + kRadius, h - 1); ++done)
      row_pass(level.ptr<std::uint8_t>(done), w, k, pad.data(), rows.data() + std::size_t(done % 8) * padded, padded);
    for (int j = -kRadius; j <= kRadius; ++j)
      r[j + kRadius] = rows.data() + std::size_t(cv::borderInterpolate(y + j, h, cv::BORDER_REFLECT_101) % 8) * padded;
    column_pass(r, k, w, padded, out.ptr<std::uint8_t>(y));
  }
}

// Hard edges, a ramp and two megapixels of noise, at sizes that are and are not multiples of 8.
// Another summation order differs from this one in the last bit of the sum, which changes the
// rounded pixel about once in 300 000 pixels: the noise is what finds it.
bool avx2_matches_opencv() {
  cv::RNG rng(0x0b1u);
  std::vector<cv::Mat> images;
  for (const cv::Size size : {cv::Size(53, 47), cv::Size(97, 61)}) {
    cv::Mat edges(size, CV_8UC1), ramp(size, CV_8UC1);
    for (int y = 0; y < size.height; ++y)
      for (int x = 0; x < size.width; ++x) {
        edges.at<std::uint8_t>(y, x) = ((x / 5 + y / 3) % 2) ? 255 : 0;
        ramp.at<std::uint8_t>(y, x) = std::uint8_t((x * 3 + y * 2) % 256);
      }
    images.insert(images.end(), {edges, ramp});
  }
  for (const int low : {0, 100}) {
    cv::Mat noise(1000, 1000, CV_8UC1);
    rng.fill(noise, cv::RNG::UNIFORM, low, 256 - low);
    images.push_back(noise);
  }
  cv::Mat ours, theirs;
  for (const cv::Mat& image : images) {
    blur_avx2(image, ours);
    blur_opencv(image, theirs);
    if (cv::norm(ours, theirs, cv::NORM_INF) != 0) return false;
  }
  return true;
}
#endif

}  // namespace

OrbBlurPath orb_blur_best_path() {
#if defined(CSLAM_ORB_BLUR_AVX2)
  static const OrbBlurPath best =
      cpu_has_avx2_fma() && avx2_matches_opencv() ? OrbBlurPath::kAvx2Fma : OrbBlurPath::kOpenCv;
  return best;
#else
  return OrbBlurPath::kOpenCv;
#endif
}

void orb_blur(const cv::Mat& level, cv::Mat& out) { orb_blur(level, out, orb_blur_best_path()); }

void orb_blur(const cv::Mat& level, cv::Mat& out, OrbBlurPath path) {
  if (level.type() != CV_8UC1) throw std::invalid_argument("orb_blur: level must be CV_8UC1");
  if (level.cols <= kRadius || level.rows <= kRadius)
    throw std::invalid_argument("orb_blur: level smaller than 4 x 4 pixels");
  if (path == OrbBlurPath::kAvx2Fma) {
#if defined(CSLAM_ORB_BLUR_AVX2)
    if (!cpu_has_avx2_fma()) throw std::invalid_argument("orb_blur: this CPU has no AVX2 and FMA");
    blur_avx2(level, out);
    return;
#else
    throw std::invalid_argument("orb_blur: built without the AVX2 path");
#endif
  }
  blur_opencv(level, out);
}

}  // namespace cslam
