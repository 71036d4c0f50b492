#pragma once
// Rotated BRIEF descriptors bit for bit as OpenCV's cv::ORB computes them for given keypoints
// (patch size 31, WTA_K 2), without what cv::ORB::compute does around them on every call: a
// bordered copy of the image, its keypoint filters and clustering, its output matrices.
//
// Same bits because every step is OpenCV's: the image is blurred exactly as cv::ORB blurs it
// (orb_blur.h: 7x7, sigma 2, reflect-101, the pixels of cv::GaussianBlur on a submatrix of a
// bordered copy, which OpenCV filters by another path than a whole image); each point of
// the 256 pairs is rotated by the keypoint's angle with the same float operations (angle in
// radians as a float, std::cos / std::sin of a float, x*cos - y*sin, x*sin + y*cos) and rounded
// to the nearest pixel as cvRound does; bit i is "first point darker than the second".
//
// The 256 point pairs are OpenCV's own (its learned pattern for a 31-pixel patch). They are read
// from the linked OpenCV once per process, by probing cv::ORB::compute with step images (no table
// is copied; orb_descriptor.cpp explains the probe), and checked against cv::ORB::compute on a
// textured image at several hundred positions and angles. If the probe or the check fails (an
// OpenCV that computes ORB otherwise), opencv_orb_pattern() is null and OrbExtractor calls
// cv::ORB::compute as before.
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include <opencv2/core.hpp>

#include "slam/features/descriptor.h"

namespace cslam {

struct OrbPattern {
  // Pair i: points (x[2i], y[2i]) and (x[2i+1], y[2i+1]), pixels from the keypoint.
  std::array<float, 512> x{}, y{};
};

// OpenCV's pattern, probed and checked once (thread-safe); null if it could not be reproduced.
const OrbPattern* opencv_orb_pattern();

// Probes the linked OpenCV for its pattern and checks it; null on any difference. Exposed for tests
// (opencv_orb_pattern() keeps the first result).
std::unique_ptr<OrbPattern> probe_opencv_orb_pattern();

// Descriptor of each keypoint of `blurred` (its pixel: cvRound of pt; at least 19 pixels from the
// border, where the rotated pattern fits), appended to `out`.
void compute_orb_descriptors(const cv::Mat& blurred, const std::vector<cv::KeyPoint>& keypoints,
                             const OrbPattern& pattern, std::vector<Descriptor>& out);

}  // namespace cslam
