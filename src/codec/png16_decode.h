#pragma once
// 16-bit greyscale PNGs (the depth images of TUM-layout datasets) decoded in one pass with
// libdeflate (no network or file code here). cv::imread / cv::imdecode go through libpng, which
// inflates with zlib row by row; libdeflate inflates the whole image data into one buffer (0.29
// instead of 1.09 ms for a fr1/rpy depth image), and the five PNG row filters are undone here,
// eight rows at a time with AVX2 or four with SSE4.1 (a scalar loop elsewhere). 2.7 -> 0.54 ms
// per image in all.
//
// Only the plain case is handled: colour type 0, bit depth 16, not interlaced, chunks IHDR, IDAT
// (consecutive), IEND and a few uncompressed metadata chunks that OpenCV 4.6 + libpng 1.6 ignore
// for such an image (gAMA cHRM sRGB sBIT bKGD pHYs tIME tEXt). Everything is checked: every
// chunk's CRC-32, every length against the buffer, the zlib stream's Adler-32, its exact end, the
// exact inflated size (a stream that wants more is corrupt) and every filter byte. Anything else,
// or anything wrong, returns false without throwing, and the caller decodes with OpenCV: the
// same pixels, or OpenCV's own error for a corrupt file. When it returns true, the pixels are
// identical to cv::imdecode(IMREAD_ANYDEPTH) (tests/codec/test_png16_decode.cpp, and
// cslam-bench-codec on the dataset files). The chunk walk, checks and inflating are shared with
// the 8-bit RGB decoder (codec/png_inflate.h); only the row filters are specific to 16-bit grey.
//
// One difference remains by construction: libdeflate accepts a few deflate streams zlib refuses
// (more than 286 literal/length or 30 distance codes in a block header, distance codes 30-31).
// No encoder writes them, and a changed byte fails the chunk's CRC first, so only a file crafted
// with valid CRC and Adler-32 decodes here where OpenCV would refuse it.
#include <cstddef>
#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

#include "codec/png_inflate.h"

namespace cslam {

// Decodes a 16-bit greyscale PNG into a CV_16UC1 image (host byte order); each side must be at
// most kMaxImageSide (image_codec.h). Returns false and leaves `out` untouched if the data is not
// such a PNG or is damaged; `why` (if given) then says why. One libdeflate decompressor and
// scratch buffers per thread, no locks: safe to call from any number of threads.
bool decode_png16_gray(const std::uint8_t* data, std::size_t size, cv::Mat& out, std::string* why = nullptr);

namespace png16_detail {

// The branch-free Paeth predictor the scalar unfiltering uses (codec/png_inflate.h).
using png_detail::paeth;

// The kernels that undo the row filters: eight rows at once with AVX2 (chosen at run time), four
// with SSE4.1 (the build's baseline), or the scalar loops. The tests compare them.
enum class UnfilterPath { kAvx2, kSse41, kScalar };
// The fastest this CPU and build have.
UnfilterPath unfilter_best_path();
// Undoes the row filters of inflated image data (height rows of a filter byte, already checked to
// be 0-4, and 2 * width bytes) into `out` (CV_16UC1, height x width, allocated), using `rows` as
// scratch, with `path` or the next one down where the CPU or the build lacks it.
void unfilter_rows(std::uint8_t* rows, int width, int height, cv::Mat& out, UnfilterPath path);

}  // namespace png16_detail

}  // namespace cslam
