#pragma once
// Internal to the fast PNG decoders (png16_decode.h, png_rgb8_decode.h): the part they share,
// everything but the row filters. Walks and checks a PNG's chunks and inflates its image data in
// one libdeflate call into a per-thread buffer. What it accepts and checks is described in
// png16_decode.h; the decoders differ only in the bit depth and colour type they ask for.
#include <cstddef>
#include <cstdint>
#include <string>

namespace cslam::png_detail {

// The one pixel format a decoder handles (always non-interlaced).
struct PngFormat {
  int bit_depth;
  int colour_type;  // PNG colour type: 0 grey, 2 RGB
  int bytes_per_pixel;
  const char* description;  // for `why`, e.g. "16-bit greyscale"
};

// The inflated image data of one PNG: `height` rows of a filter byte (checked to be 0-4) and
// row_bytes = width * bytes_per_pixel filtered bytes, stride = row_bytes + 1 apart, in the calling
// thread's scratch buffer (writable: a decoder may unfilter in place). Valid until this object is
// destroyed or the same thread inflates another PNG; destroying it releases the thread's buffers
// if they grew unusually large, so declare it before calling inflate_png.
class InflatedPng {
 public:
  InflatedPng() = default;
  ~InflatedPng();
  InflatedPng(const InflatedPng&) = delete;
  InflatedPng& operator=(const InflatedPng&) = delete;

  int width = 0, height = 0;
  std::size_t row_bytes = 0, stride = 0;
  std::uint8_t* rows = nullptr;
};

// Inflates the image data of a PNG of the given format into `png`. Returns false (with `why` if
// given) if the data is anything else or damaged; never throws for bad data.
bool inflate_png(const std::uint8_t* data, std::size_t size, const PngFormat& format, InflatedPng& png,
                 std::string* why);

// The PNG Paeth predictor (a: left, b: above, c: above-left), in a branch-free form: the spec's
// nearest of a, b, c to a + b - c, ties to a then b. For lo = min(a, b), hi = max(a, b) and
// t = 3c - a - b: c <= lo gives hi, c >= hi gives lo; in between, hi wins while t <= lo, lo
// while t >= hi, and c otherwise. Checked against the spec for all 2^24 inputs in the tests.
// Used by the scalar unfiltering; the selections are masks because compilers otherwise turn one
// of them into a branch, which mispredicts on real images.
inline int paeth(int a, int b, int c) {
  const int t = 3 * c - a - b;
  const int lo = a < b ? a : b;
  const int hi = a < b ? b : a;
  const int take_lo = -int(hi <= t);  // all ones or zero
  const int take_hi = -int(t <= lo);
  const int lo_or_c = c ^ ((lo ^ c) & take_lo);
  return lo_or_c ^ ((hi ^ lo_or_c) & take_hi);
}

}  // namespace cslam::png_detail
