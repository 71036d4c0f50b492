#pragma once
// A bounded pre-check of a PNG stream before it is decoded (no network code here). A PNG header
// may announce a small image while its compressed stream inflates to gigabytes (a decompression
// bomb), and a decoder that keeps inflating stalls its thread. check_png_stream walks the chunks,
// allows only the chunk types a plain image needs (no compressed text or ICC profiles), and
// inflates the image data into a bounded scratch buffer: the stream must produce exactly the
// bytes the header's size, depth, colour type and interlacing imply; one byte more is corrupt.
// Work is bounded by the expected size and by a time budget.
#include <cstddef>
#include <cstdint>
#include <string>

namespace cslam {

struct PngLimits {
  int width = 0, height = 0;  // the image size the caller expects (the header must agree)
  bool depth16_grey = false;  // require a 16-bit grey image (depth)
  // Inflating for more than this much of the thread's CPU time is an error (0: no budget). CPU
  // time, not wall clock: on a loaded machine a good image that waits for a core is not refused.
  double time_budget_ms = 250;
};

// Throws InputError(source, ...) on anything but a well-formed PNG of the expected size.
void check_png_stream(const std::uint8_t* data, std::size_t size, const PngLimits& limits, const std::string& source);

// Bytes the inflated image data of a width x height PNG must have (filter bytes included).
std::size_t png_inflated_size(int width, int height, int bit_depth, int color_type, bool interlaced);

}  // namespace cslam
