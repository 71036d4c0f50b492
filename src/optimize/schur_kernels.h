#pragma once
// The inner kernel of the Schur-complement local BA: eliminating one point subtracts
// T_e * W_f^T from the reduced camera system's block (cam_e, cam_f) for every pair of the
// point's free-camera observations (T_e = W_e V^-1). It is most of the solver's arithmetic.
//
// Two implementations with one contract: the portable one (Eigen, the machine's baseline ISA)
// and an AVX2+FMA one, chosen once at run time when the CPU has both. Fused multiply-adds round
// once per product, so their sums differ from the portable ones in the last bits.
#include <cstddef>

namespace cslam::schur_kernels {

// For i, j in [0, m) with cam[j] <= cam[i]: the 6x6 block of S at rows 6 cam[i], columns 6 cam[j]
// -= T[i] * W[j]^T. T[i] and W[i] are 6x3 column-major (Eigen's Matrix<double, 6, 3>); S is
// column-major with leading dimension ld. Only S's lower block triangle is written.
using PairProductsFn = void (*)(const double* const* T, const double* const* W, const int* cam, int m, double* S,
                                std::ptrdiff_t ld);

void pair_products_portable(const double* const* T, const double* const* W, const int* cam, int m, double* S,
                            std::ptrdiff_t ld);

// Call it only when cpu_has_avx2_fma() (core/cpu_features.h); elsewhere than x86-64 it is the
// portable one.
void pair_products_avx2(const double* const* T, const double* const* W, const int* cam, int m, double* S,
                        std::ptrdiff_t ld);

// The implementation this machine runs (chosen on first use).
PairProductsFn pair_products();
const char* pair_products_isa();  // "avx2-fma" or "portable"

}  // namespace cslam::schur_kernels
