#pragma once
// The codec libraries with large dependency trees, loaded on first use: OpenCV's image codecs
// (cv::imdecode and friends: other formats than the JPEG and PNG decoded here; the encoders) and
// libavcodec (H.264). Linked into every program, their dependency trees (GDAL, DCMTK, x264, ...)
// brought a process to 226 shared libraries, whose symbols Debian's BIND_NOW builds resolve at
// every start: ~130 ms of CPU per process, before any of them was used. Each is now a plugin
// (build/lib/cslam/, /opt/cslam/lib/cslam/ in the image) that the dynamic loader maps only when a
// frame or file first needs it.
//
// A plugin is looked for in ../lib/cslam/ beside the running executable (programs in bin/, tests
// in tests/). A missing or unloadable plugin throws std::runtime_error naming its path and the
// loader's reason; loading happens once per process (the loader keeps it mapped until exit).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace cslam {

// OpenCV's image codecs (opencv_image_io_plugin.cpp): the same calls, the same results.
struct ImageIoApi {
  cv::Mat (*imdecode)(const cv::Mat& bytes, int flags);
  bool (*imencode)(const std::string& ext, const cv::Mat& image, std::vector<std::uint8_t>& out,
                   const std::vector<int>& params);
  cv::Mat (*imread)(const std::string& path, int flags);
  bool (*imwrite)(const std::string& path, const cv::Mat& image, const std::vector<int>& params);
};
const ImageIoApi& image_io();

namespace video {
struct H264Options;

// libavcodec's side of the H.264 codec (h264_plugin.cpp); video_codec.h adds the packet
// header, the chain rules and the colour conversion. The engines throw std::runtime_error (the
// decoder returns what is wrong with a unit instead).
class H264EncoderEngine {
 public:
  virtual ~H264EncoderEngine() = default;
  // i420: (height * 3 / 2) x width, CV_8UC1 (Y, then U and V). Appends the frame's one access
  // unit to `out` (after whatever the caller put there, e.g. a packet header); key: whether it is
  // an IDR picture.
  virtual void encode(const cv::Mat& i420, std::int64_t pts, bool force_key, std::vector<std::uint8_t>& out,
                      bool& key) = 0;
};
class H264DecoderEngine {
 public:
  virtual ~H264DecoderEngine() = default;
  // Decodes one access unit into i420 ((height * 3 / 2) x width, allocated by the caller).
  // Returns an empty string, or why the unit is corrupt.
  virtual std::string decode(const std::uint8_t* data, std::size_t size, cv::Mat& i420) = 0;
  virtual void flush() = 0;  // drops the reference pictures (the chain is broken)
};
struct H264Api {
  // Sizes are checked by the caller; options validated.
  H264EncoderEngine* (*make_encoder)(int width, int height, const H264Options& options);
  H264DecoderEngine* (*make_decoder)(int width, int height);
};
const H264Api& h264_engine();
}  // namespace video

}  // namespace cslam
