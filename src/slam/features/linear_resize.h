#pragma once
// Bilinear downscaling of 8-bit grey images bit for bit as cv::resize(..., cv::INTER_LINEAR), for
// the ORB pyramid (each level is the previous one resized by 1/scale_factor).
//
// Why not cv::resize: for a non-integer scale it builds its coefficient tables, row buffers and a
// parallel loop on every call, which cost about as much as the interpolation at these sizes.
//
// Same pixels because every step is OpenCV's fixed-point path for 8-bit images: source positions
// (dx + 0.5) * scale - 0.5 computed in double and rounded to float, coefficients 1 - f and f
// rounded to 11-bit fixed point (2048), a horizontal pass into 32-bit sums (S[x] * a0 + S[x+1] * a1,
// S[x] * 2048 where the right neighbour falls outside), then the vertical blend. OpenCV's vertical
// blend rounds two ways: its vector code ((((r0 >> 4) * b0) >> 16) + (((r1 >> 4) * b1) >> 16) + 2) >> 2
// for the columns it covers, its scalar code (r0 * b0 + r1 * b1 + 2^21) >> 22 for the rest. Which
// columns get which depends on how OpenCV was built (Debian 12's OpenCV 4.6 rounds every column the
// vector way); it is found by comparing against cv::resize on noise images once per process, and
// if no candidate reproduces it, opencv_linear_resize() is null and callers use cv::resize.
// Enlarging goes another way in OpenCV and is not offered.
#include <memory>

#include <opencv2/core.hpp>

namespace cslam {

struct LinearResize {
  // Columns [0, width rounded down to a multiple of this) use the vector rounding (1: all; 0: none).
  int vector_columns = 1;
};

// The rule that reproduces the linked OpenCV, found and checked once (thread-safe); null if none does.
const LinearResize* opencv_linear_resize();

// Tries each candidate rule against cv::resize on noise images of many sizes; null on any
// difference. Exposed for tests (opencv_linear_resize() keeps the first result).
std::unique_ptr<LinearResize> probe_opencv_linear_resize();

// `src` (CV_8UC1, not empty) shrunk to `size` (at most src's size on each axis) into `dst`
// (reallocated if needed; it may be src itself). Throws std::invalid_argument on another type, an
// empty or a larger size.
void resize_linear(const cv::Mat& src, cv::Mat& dst, cv::Size size, const LinearResize& rule);

}  // namespace cslam
