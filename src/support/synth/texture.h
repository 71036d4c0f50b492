#pragma once
// Procedural surface textures: multi-scale colour noise plus random shapes, stripe patches,
// glyph-like strokes and characters at several scales, high contrast and non-periodic, so ORB
// finds many distinctive corners at every pyramid level and no two places look alike.
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace cslam::synth {

// Unshaded albedo (CV_8UC3 BGR) for a surface of size_u x size_v metres at texel_size metres per
// texel: columns follow u, rows follow v. Deterministic in (sizes, texel_size, seed).
cv::Mat make_albedo_texture(double size_u, double size_v, double texel_size, std::uint64_t seed);

// Level 0 followed by successive 2x box-filtered reductions down to a few texels.
std::vector<cv::Mat> make_mip_chain(const cv::Mat& level0);

}  // namespace cslam::synth
