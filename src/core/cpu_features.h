#pragma once
// What the CPU the program runs on can do, for kernels compiled with target attributes for a
// wider instruction set than the build's baseline and chosen at run time (x86-64 with GCC or
// Clang; false elsewhere). Each answer is looked up once.
namespace cslam {

inline bool cpu_has_avx2() {
#if defined(__x86_64__) && defined(__GNUC__)
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
#else
  return false;
#endif
}

inline bool cpu_has_avx2_fma() {
#if defined(__x86_64__) && defined(__GNUC__)
  static const bool has = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return has;
#else
  return false;
#endif
}

}  // namespace cslam
