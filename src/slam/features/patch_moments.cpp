#include "slam/features/patch_moments.h"

#include <array>
#include <cmath>

#if defined(__SSSE3__)
#include <tmmintrin.h>
#endif

namespace cslam {

namespace {

struct Tables {
  std::array<int, kPatchRadius + 1> half_width{};
  // Per |row offset| v, over the 32 columns u = -16..15: the weight u inside the disc's row (0
  // outside), and 1 inside (0 outside).
  alignas(16) std::array<std::array<std::int8_t, 32>, kPatchRadius + 1> weight{}, inside{};
  Tables() {
    for (int v = 0; v <= kPatchRadius; ++v) {
      half_width[v] = int(std::floor(std::sqrt(double(kPatchRadius * kPatchRadius - v * v)) + 0.5));
      for (int i = 0; i < 32; ++i) {
        const int u = i - 16;
        const bool in = u >= -half_width[v] && u <= half_width[v];
        weight[v][i] = std::int8_t(in ? u : 0);
        inside[v][i] = std::int8_t(in ? 1 : 0);
      }
    }
  }
};

const Tables& tables() {
  static const Tables t;  // immutable after construction (thread-safe initialisation)
  return t;
}

}  // namespace

const int* patch_row_half_widths() { return tables().half_width.data(); }

PatchMoments patch_moments_reference(const std::uint8_t* center, int step) {
  const int* umax = patch_row_half_widths();
  PatchMoments m;
  for (int u = -kPatchRadius; u <= kPatchRadius; ++u) m.m10 += u * center[u];
  for (int v = 1; v <= kPatchRadius; ++v) {
    int v_sum = 0;
    const int d = umax[v];
    for (int u = -d; u <= d; ++u) {
      const int above = center[u - v * step], below = center[u + v * step];
      v_sum += below - above;
      m.m10 += u * (below + above);
    }
    m.m01 += v * v_sum;
  }
  return m;
}

PatchMoments patch_moments(const std::uint8_t* center, int step) {
#if defined(__SSSE3__)
  const Tables& t = tables();
  const __m128i ones = _mm_set1_epi16(1);
  // One row: (sum of u * I, sum of I) over the row's span, as 32-bit lanes to be added up.
  auto row = [&](const std::uint8_t* p, int v, __m128i& wsum, __m128i& sum) {
    const __m128i lo = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p - 16));
    const __m128i hi = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p));
    const __m128i* w = reinterpret_cast<const __m128i*>(t.weight[v].data());
    const __m128i* in = reinterpret_cast<const __m128i*>(t.inside[v].data());
    // maddubs: unsigned pixel x signed weight, adjacent pairs summed to int16 (|.| <= 2 * 255 * 16).
    const __m128i wl =
        _mm_add_epi16(_mm_maddubs_epi16(lo, _mm_load_si128(w)), _mm_maddubs_epi16(hi, _mm_load_si128(w + 1)));
    const __m128i sl =
        _mm_add_epi16(_mm_maddubs_epi16(lo, _mm_load_si128(in)), _mm_maddubs_epi16(hi, _mm_load_si128(in + 1)));
    wsum = _mm_madd_epi16(wl, ones);
    sum = _mm_madd_epi16(sl, ones);
  };
  auto hsum = [](__m128i x) {
    x = _mm_add_epi32(x, _mm_shuffle_epi32(x, _MM_SHUFFLE(1, 0, 3, 2)));
    x = _mm_add_epi32(x, _mm_shuffle_epi32(x, _MM_SHUFFLE(2, 3, 0, 1)));
    return _mm_cvtsi128_si32(x);
  };
  __m128i m10 = _mm_setzero_si128(), m01 = _mm_setzero_si128(), wsum, sum;
  row(center, 0, wsum, sum);
  m10 = wsum;
  for (int v = 1; v <= kPatchRadius; ++v) {
    __m128i wa, sa, wb, sb;
    row(center - v * step, v, wa, sa);
    row(center + v * step, v, wb, sb);
    m10 = _mm_add_epi32(m10, _mm_add_epi32(wa, wb));
    // Each lane's difference fits in int16 (4 pixels): madd with (v, 0) multiplies it by v.
    m01 = _mm_add_epi32(m01, _mm_madd_epi16(_mm_sub_epi32(sb, sa), _mm_set1_epi32(v)));
  }
  return {hsum(m10), hsum(m01)};
#else
  return patch_moments_reference(center, step);
#endif
}

}  // namespace cslam
