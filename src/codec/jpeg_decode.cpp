#include "codec/jpeg_decode.h"

#include <climits>
#include <memory>
#include <stdexcept>
#include <string>

#include <opencv2/imgcodecs.hpp>
#include <turbojpeg.h>

#include "codec/codec_plugins.h"
#include "codec/image_codec.h"
#include "core/error.h"

namespace cslam {

namespace {

// One decompressor per thread: a tjhandle must not be shared between threads, and creating one
// per image would allocate libjpeg's state every time. After any error it is replaced: in
// libjpeg-turbo 2.1.5, tjDecompressHeader3 returns from its error handler without aborting the
// decompressor, which stays half-way through the bad header, and the next image on that handle
// fails ("Bogus Huffman table definition"); one bad packet would break the thread's decoding.
struct TjDeleter {
  void operator()(void* h) const { tjDestroy(h); }
};
using TjHandle = std::unique_ptr<void, TjDeleter>;

TjHandle& thread_handle() {
  thread_local TjHandle handle;
  return handle;
}

tjhandle thread_decompressor() {
  TjHandle& handle = thread_handle();
  if (!handle) handle.reset(tjInitDecompress());
  if (!handle)
    throw std::runtime_error(std::string("TurboJPEG: cannot create a decompressor: ") + tjGetErrorStr2(nullptr));
  return handle.get();
}

std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

// Throws for the last TurboJPEG error on this thread's decompressor, which is then replaced.
[[noreturn]] void throw_corrupt(tjhandle tj, const std::string& source) {
  const std::string message = std::string("corrupt JPEG: ") + tjGetErrorStr2(tj);
  thread_handle().reset();
  throw InputError(source, message);
}

}  // namespace

bool looks_like_jpeg(const std::uint8_t* data, std::size_t size) {
  return size >= 3 && data[0] == 0xff && data[1] == 0xd8 && data[2] == 0xff;
}

cv::Mat decode_jpeg_bgr(const std::uint8_t* data, std::size_t size, const std::string& source, int width, int height) {
  if (!looks_like_jpeg(data, size)) throw InputError(source, "not a JPEG image");
  if (size > std::size_t(ULONG_MAX)) throw InputError(source, "JPEG too large");
  tjhandle tj = thread_decompressor();
  int w = 0, h = 0, subsampling = 0, colorspace = 0;
  if (tjDecompressHeader3(tj, data, static_cast<unsigned long>(size), &w, &h, &subsampling, &colorspace) != 0)
    throw_corrupt(tj, source);
  if (w <= 0 || h <= 0 || w > kMaxImageSide || h > kMaxImageSide)
    throw InputError(source, "JPEG size " + size_text(w, h) + " out of range");
  if ((width > 0 || height > 0) && (w != width || h != height))
    throw InputError(source, "JPEG is " + size_text(w, h) + ", expected " + size_text(width, height));
  if (colorspace == TJCS_CMYK || colorspace == TJCS_YCCK) {
    cv::Mat out;
    try {
      out = image_io().imdecode(cv::Mat(1, int(size), CV_8UC1, const_cast<std::uint8_t*>(data)),
                                cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
    } catch (const cv::Exception&) {
    }
    if (out.empty() || out.type() != CV_8UC3 || out.cols != w || out.rows != h)
      throw InputError(source, "CMYK JPEG could not be decoded");
    return out;
  }
  cv::Mat out(h, w, CV_8UC3);
  // Accurate DCT and fancy upsampling are libjpeg's defaults and OpenCV's: bit-exact output.
  // STOPONWARNING: a damaged stream stops at once instead of being decoded to the end and refused.
  // LIMITSCANS: at most 500 progressive scans (decode_rgb allows network peers far fewer).
  const int flags = TJFLAG_ACCURATEDCT | TJFLAG_STOPONWARNING | TJFLAG_LIMITSCANS;
  if (tjDecompress2(tj, data, static_cast<unsigned long>(size), out.data, w, int(out.step[0]), h, TJPF_BGR, flags) != 0)
    throw_corrupt(tj, source);
  return out;
}

}  // namespace cslam
