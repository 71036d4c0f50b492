// Plugin: OpenCV's image codecs behind codec/codec_plugins.h's ImageIoApi (loaded on first use).
#include <opencv2/imgcodecs.hpp>

#include "codec/codec_plugins.h"

namespace {

cv::Mat imdecode(const cv::Mat& bytes, int flags) { return cv::imdecode(bytes, flags); }
bool imencode(const std::string& ext, const cv::Mat& image, std::vector<std::uint8_t>& out,
              const std::vector<int>& params) {
  return cv::imencode(ext, image, out, params);
}
cv::Mat imread(const std::string& path, int flags) { return cv::imread(path, flags); }
bool imwrite(const std::string& path, const cv::Mat& image, const std::vector<int>& params) {
  return cv::imwrite(path, image, params);
}

const cslam::ImageIoApi kApi{imdecode, imencode, imread, imwrite};

}  // namespace

extern "C" __attribute__((visibility("default"))) const void* cslam_image_io_api() { return &kApi; }
