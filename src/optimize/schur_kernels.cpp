#include "optimize/schur_kernels.h"

#include <Eigen/Core>

#include "core/cpu_features.h"

#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace cslam::schur_kernels {

namespace {
using Matrix63d = Eigen::Matrix<double, 6, 3>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
}  // namespace

void pair_products_portable(const double* const* T, const double* const* W, const int* cam, int m, double* S,
                            std::ptrdiff_t ld) {
  for (int i = 0; i < m; ++i) {
    const Eigen::Map<const Matrix63d> Ti(T[i]);
    for (int j = 0; j < m; ++j) {
      if (cam[j] > cam[i]) continue;
      Eigen::Map<Matrix6d, 0, Eigen::OuterStride<>> block(S + 6 * (cam[j] * ld + cam[i]), Eigen::OuterStride<>(ld));
      block.noalias() -= Ti * Eigen::Map<const Matrix63d>(W[j]).transpose();
    }
  }
}

#if defined(__x86_64__)

// Block column c gets -= T(:,0) W(c,0) + T(:,1) W(c,1) + T(:,2) W(c,2): rows 0-3 in one 256-bit
// register, rows 4-5 in one 128-bit register, three fused multiply-subtracts each.
__attribute__((target("avx2,fma"))) void pair_products_avx2(const double* const* T, const double* const* W,
                                                            const int* cam, int m, double* S, std::ptrdiff_t ld) {
  for (int i = 0; i < m; ++i) {
    const double* t = T[i];
    const __m256d t0 = _mm256_loadu_pd(t), t1 = _mm256_loadu_pd(t + 6), t2 = _mm256_loadu_pd(t + 12);
    const __m128d u0 = _mm_loadu_pd(t + 4), u1 = _mm_loadu_pd(t + 10), u2 = _mm_loadu_pd(t + 16);
    for (int j = 0; j < m; ++j) {
      if (cam[j] > cam[i]) continue;
      const double* w = W[j];
      double* col = S + 6 * (cam[j] * ld + cam[i]);
      for (int c = 0; c < 6; ++c, col += ld) {
        const __m256d w0 = _mm256_broadcast_sd(w + c), w1 = _mm256_broadcast_sd(w + 6 + c),
                      w2 = _mm256_broadcast_sd(w + 12 + c);
        __m256d lo = _mm256_loadu_pd(col);
        lo = _mm256_fnmadd_pd(t0, w0, lo);
        lo = _mm256_fnmadd_pd(t1, w1, lo);
        lo = _mm256_fnmadd_pd(t2, w2, lo);
        _mm256_storeu_pd(col, lo);
        __m128d hi = _mm_loadu_pd(col + 4);
        hi = _mm_fnmadd_pd(u0, _mm256_castpd256_pd128(w0), hi);
        hi = _mm_fnmadd_pd(u1, _mm256_castpd256_pd128(w1), hi);
        hi = _mm_fnmadd_pd(u2, _mm256_castpd256_pd128(w2), hi);
        _mm_storeu_pd(col + 4, hi);
      }
    }
  }
}

#else

void pair_products_avx2(const double* const* T, const double* const* W, const int* cam, int m, double* S,
                        std::ptrdiff_t ld) {
  pair_products_portable(T, W, cam, m, S, ld);
}

#endif

PairProductsFn pair_products() {
  static const PairProductsFn chosen = cpu_has_avx2_fma() ? &pair_products_avx2 : &pair_products_portable;
  return chosen;
}

const char* pair_products_isa() { return pair_products() == &pair_products_avx2 ? "avx2-fma" : "portable"; }

}  // namespace cslam::schur_kernels
