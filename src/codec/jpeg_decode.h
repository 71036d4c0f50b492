#pragma once
// JPEG to BGR in one step with libjpeg-turbo's TurboJPEG API (no network or file code here).
// cv::imread / cv::imdecode (OpenCV 4.6) ask libjpeg for RGB and then swap every pixel to BGR in
// a byte loop that costs as much as the decoding itself; TurboJPEG writes BGR directly. The
// decoder settings are libjpeg's defaults, the ones OpenCV uses (accurate integer DCT, "fancy"
// upsampling), so the pixels are bit-identical to cv::imdecode(IMREAD_COLOR) with the same
// libjpeg-turbo (tests/codec/test_jpeg_decode.cpp, and cslam-bench-codec on the dataset files).
#include <cstddef>
#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

namespace cslam {

// Decodes a JPEG into a CV_8UC3 BGR image. If width and height are > 0, the JPEG must be exactly
// that size (checked from its header before decoding); either way each side must be at most
// kMaxImageSide (image_codec.h). Greyscale JPEGs come out as three equal channels; CMYK/YCCK
// JPEGs (which TurboJPEG cannot turn into BGR) are handed to cv::imdecode. EXIF orientation is
// not applied. Throws InputError(source, ...) if the data is not a JPEG, is corrupt or truncated
// (libjpeg's warnings, e.g. "premature end of data segment", count as corrupt) or has the wrong size.
cv::Mat decode_jpeg_bgr(const std::uint8_t* data, std::size_t size, const std::string& source, int width = 0,
                        int height = 0);

// True if the bytes start like a JPEG (SOI marker followed by another marker).
bool looks_like_jpeg(const std::uint8_t* data, std::size_t size);

}  // namespace cslam
