#pragma once
// The blur cv::ORB applies to a pyramid level before its intensity tests (7x7 Gaussian, sigma 2,
// reflect-101 beyond the level's border), bit for bit, without a bordered copy of the level.
//
// Why not cv::GaussianBlur: cv::ORB blurs a submatrix of a bordered copy, which OpenCV filters by
// its generic floating-point path (a row pass into floats, a column pass back to 8 bits) with a
// filter engine set up on every call; here neither the copy nor the engine is needed (the gain:
// docs/features_bow.md).
//
// Same pixels because every operation is that path's, in its order: the kernel k is
// cv::getGaussianKernel(7, 2, CV_32F); the row pass starts from k0 * s[x - 3] and adds
// k_j * s[x - 3 + j] for j = 1 .. 6 by fused multiply-add; the column pass starts from
// k3 * r[y] and adds (r[y + j] + r[y - j]) * k_(3 + j) for j = 1 .. 3 by fused multiply-add; the
// sum is rounded to the nearest integer (ties to even) and saturated. That is how Debian 12's
// OpenCV 4.6 computes it on a CPU with AVX2 and FMA. Another build or CPU may sum otherwise, so
// the fast path is compared against cv::GaussianBlur on noise and edge images once per process and
// used only if every pixel agrees; otherwise cv::GaussianBlur runs as cv::ORB calls it.
#include <opencv2/core.hpp>

namespace cslam {

enum class OrbBlurPath { kOpenCv, kAvx2Fma };

// The path that reproduces the linked OpenCV on this CPU, found once (thread-safe).
OrbBlurPath orb_blur_best_path();

// `level` (CV_8UC1, at least 4 x 4 pixels) blurred into `out` (reallocated to its size) by the best
// path. Throws std::invalid_argument on another type or a smaller image.
void orb_blur(const cv::Mat& level, cv::Mat& out);
// By the given path; kAvx2Fma throws std::invalid_argument on a CPU without AVX2 and FMA.
void orb_blur(const cv::Mat& level, cv::Mat& out, OrbBlurPath path);

}  // namespace cslam
