#pragma once
// FAST-9 corners (Rosten & Drummond 2006: 9 contiguous pixels of the radius-3, 16-pixel circle
// all brighter or all darker than the centre by more than the threshold) with non-maximum
// suppression, giving exactly the corners, responses and order of
// cv::FAST(image, keypoints, threshold, true) (TYPE_9_16).
//
// Why not cv::FAST: it scores each corner on its own, in scalar code, and the score is most of
// its time wherever corners are dense (ORB's fallback threshold of 7 over weak cells finds a
// corner at most pixels). Here the score of every pixel of a 32- (AVX2) or 16-pixel (SSE2) block
// that may hold a corner is computed at once, and the suppression runs 16 pixels at a time:
//   score = max over the 16 arcs of 9 contiguous circle pixels of the smallest difference
//           to the centre along the arc (darker and brighter side), minus 1,
// the highest threshold at which the pixel is still a corner, so a pixel is a corner exactly
// when score >= threshold. Non-maximum suppression keeps a corner whose score is above all eight
// neighbours' (0 for a non-corner).
#include <array>
#include <vector>

#include <opencv2/core.hpp>

namespace cslam {

// Corners of an 8-bit single-channel image (a view into a larger image is fine: only its own
// pixels are read). Corners lie at least 3 pixels inside the image; in raster order, as
// cv::KeyPoint(x, y, 7, -1, score).
void detect_fast_corners(const cv::Mat& image, int threshold, std::vector<cv::KeyPoint>& keypoints);

// The implementations, all with the same result: AVX2 (32 pixels a step, when the CPU has it),
// SSE2 (16) and pixel by pixel. The fastest available runs by default; tests run each.
enum class FastCornersPath { kAvx2, kSse2, kScalar };
FastCornersPath fast_corners_best_path();
void detect_fast_corners(const cv::Mat& image, int threshold, std::vector<cv::KeyPoint>& keypoints,
                         FastCornersPath path);

// The plain per-pixel score (-1 and below: no corner at any threshold); the vector code's second
// opinion in tests.
int fast_corner_score(const cv::Mat& image, int x, int y);

// max(0, fast_corner_score) of the four neighbours of (x, y): left, right, above, below. The
// pixel must lie at least 4 inside the image (std::invalid_argument otherwise). Vector code where
// the image is wide enough around it; equal to the plain score in every case (tested).
std::array<int, 4> fast_neighbour_scores(const cv::Mat& image, int x, int y);

}  // namespace cslam
