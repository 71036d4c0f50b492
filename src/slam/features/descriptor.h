#pragma once
// 256-bit binary descriptors (rotated BRIEF) as four 64-bit words, and their Hamming distance.
// Bit i of byte j of OpenCV's 1x32 CV_8U row is bit (8*j + i) of the 256-bit value, i.e. bit
// (8*(j%8) + i) of word j/8 on a little-endian machine (the row is copied byte for byte).
#include <array>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace cslam {

using Descriptor = std::array<std::uint64_t, 4>;

inline int hamming_distance(const Descriptor& a, const Descriptor& b) {
  return __builtin_popcountll(a[0] ^ b[0]) + __builtin_popcountll(a[1] ^ b[1]) + __builtin_popcountll(a[2] ^ b[2]) +
         __builtin_popcountll(a[3] ^ b[3]);
}

// Reference implementation (bit by bit), for tests.
int hamming_distance_naive(const Descriptor& a, const Descriptor& b);

// Bit `i` (0..255) of a descriptor, bit i%8 of byte i/8 as in OpenCV's row layout.
inline bool descriptor_bit(const Descriptor& d, int i) {
  return (reinterpret_cast<const std::uint8_t*>(d.data())[i >> 3] >> (i & 7)) & 1u;
}

// CV_8U 1x32 row -> Descriptor. Throws std::invalid_argument on another shape or type.
Descriptor descriptor_from_row(const cv::Mat& row);
// Descriptor -> CV_8U 1x32 row.
cv::Mat descriptor_to_row(const Descriptor& d);
// N x 32 CV_8U matrix -> descriptors (empty matrix -> empty vector).
std::vector<Descriptor> descriptors_from_mat(const cv::Mat& mat);

}  // namespace cslam
