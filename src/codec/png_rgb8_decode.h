#pragma once
// 8-bit RGB PNGs (the colour images of TUM RGB-D datasets as published) decoded in one pass with
// libdeflate (no network or file code here), like the depth images (png16_decode.h): the chunk
// walk, its checks and the inflating are the same code (png_inflate.h), and the row filters are
// undone here for 3-byte pixels, writing BGR as cv::imdecode(IMREAD_COLOR) does. Per 640x480
// image (60 fr1/rpy frames written as PNG, thread CPU): 4.6 -> 2.2 ms with OpenCV's default PNG
// settings (Sub filter, zlib level 1 RLE: inflating is 1.9 ms of it), 7.6 -> 1.8 ms with zlib
// level 6 or 9 and libpng's adaptive filters (mostly Paeth; inflating 1.3 ms).
//
// Only the plain case is handled: colour type 2, bit depth 8, not interlaced, chunks IHDR, IDAT
// (consecutive), IEND and the uncompressed metadata chunks OpenCV 4.6 + libpng 1.6 do not apply
// (gAMA cHRM sRGB sBIT bKGD pHYs tIME tEXt). A tRNS chunk (OpenCV then decodes to 4 channels),
// PLTE, iCCP, eXIf, anything unknown, any other bit depth, colour type or interlacing, and any
// damage (CRC, length, Adler-32, inflated size, filter byte) returns false without throwing; the
// caller then decodes with OpenCV. When it returns true, the pixels are identical to
// cv::imdecode(IMREAD_COLOR) (tests/codec/test_png_rgb8_decode.cpp). The difference left by
// construction is png16_decode.h's: a few deflate streams only a crafted file has, which
// libdeflate accepts and zlib refuses.
#include <cstddef>
#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

namespace cslam {

// Decodes an 8-bit RGB PNG into a CV_8UC3 BGR image; each side must be at most kMaxImageSide
// (image_codec.h). Returns false and leaves `out` untouched if the data is not such a PNG or is
// damaged; `why` (if given) then says why. One libdeflate decompressor and scratch buffers per
// thread, no locks: safe to call from any number of threads.
bool decode_png_rgb8(const std::uint8_t* data, std::size_t size, cv::Mat& out, std::string* why = nullptr);

namespace png_rgb8_detail {

// Undoes the row filters of inflated RGB image data (height rows of a filter byte, already checked
// to be 0-4, and 3 * width bytes; `rows` is only read) into `out` (CV_8UC3, height x width,
// allocated), swapping R and B. simd: the SSE4.1 kernel where the build has it, else the scalar
// one (tests compare them).
void unfilter_rows(const std::uint8_t* rows, int width, int height, cv::Mat& out, bool simd);

// out[i] = Paeth predictor of (a[i], b[i], c[i]) for i < n, by the vector kernel's byte-lane
// formula where the build has SSE4.1 (else the scalar one); exposed for the exhaustive test.
void paeth_predict(const std::uint8_t* a, const std::uint8_t* b, const std::uint8_t* c, std::uint8_t* out,
                   std::size_t n);

}  // namespace png_rgb8_detail

}  // namespace cslam
