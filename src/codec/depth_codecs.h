#pragma once
// Lossless 16-bit depth codecs used by image_codec: RVL and zstd of a delta-coded image.
//  - RVL (Wilson, "Fast lossless depth image compression", 2017): runs of zeros and non-zeros,
//    non-zero values as zig-zag deltas to the previous non-zero value, packed in 4-bit nibbles
//    (3 data bits + continuation bit). Our own implementation from the paper's description.
//  - zstd-delta: the image's distinct values as a sorted table, the hole mask, and each valid
//    pixel's rank in that table predicted from its valid causal neighbours (JPEG-LS's median edge
//    detector), the zig-zag residuals split into a low-byte and a high-byte plane; then zstd.
//    Layout in depth_codecs.cpp.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace cslam::depth_codec {

std::vector<std::uint8_t> rvl_encode(const std::uint16_t* pixels, std::size_t count);
// Throws InputError(source, ...) unless the bytes decode to exactly `count` pixels.
void rvl_decode(const std::uint8_t* data, std::size_t size, std::uint16_t* pixels, std::size_t count,
                const std::string& source);

std::vector<std::uint8_t> zstd_delta_encode(const std::uint16_t* pixels, int width, int height, int level);
void zstd_delta_decode(const std::uint8_t* data, std::size_t size, std::uint16_t* pixels, int width, int height,
                       const std::string& source);

}  // namespace cslam::depth_codec
