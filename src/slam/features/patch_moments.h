#pragma once
// First-order intensity moments of ORB's circular patch (radius 15) around a pixel, whose angle
// atan2(m01, m10) is the keypoint's orientation (intensity centroid, Rosin 1999; ORB, Rublee et
// al. 2011). Integer sums, so the vectorised and the plain versions agree exactly.
#include <cstdint>

namespace cslam {

struct PatchMoments {
  int m10 = 0;  // sum of u * I(u, v) over the disc (u: column offset)
  int m01 = 0;  // sum of v * I(u, v) (v: row offset, downwards)
};

constexpr int kPatchRadius = 15;

// Half-width of the disc's row at |row offset| v, for v = 0..15 (floor(sqrt(15^2 - v^2) + 0.5)).
const int* patch_row_half_widths();

// The moments around `center` (row stride `step` bytes). The disc, and one byte left of each row
// (read, with zero weight, by the vectorised version), must be inside the image.
PatchMoments patch_moments(const std::uint8_t* center, int step);

// The plain loops: reference for tests, and the path without SSSE3.
PatchMoments patch_moments_reference(const std::uint8_t* center, int step);

}  // namespace cslam
