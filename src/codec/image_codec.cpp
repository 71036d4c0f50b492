#include "codec/image_codec.h"

#include <cstring>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>

#include "codec/codec_plugins.h"
#include "codec/depth_codecs.h"
#include "codec/jpeg_decode.h"
#include "codec/png16_decode.h"
#include "codec/png_guard.h"
#include "codec/png_rgb8_decode.h"
#include "codec/video_codec.h"
#include "core/error.h"

namespace cslam {

namespace {

std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

void check_announced_size(int width, int height, const std::string& source) {
  if (width <= 0 || height <= 0 || width > kMaxImageSide || height > kMaxImageSide)
    throw InputError(source, "image size " + size_text(width, height) + " out of range");
}

std::uint32_t be32(const std::uint8_t* p) {
  return (std::uint32_t(p[0]) << 24) | (std::uint32_t(p[1]) << 16) | (std::uint32_t(p[2]) << 8) | p[3];
}

// Reads width/height from a PNG header without decoding (so a tiny PNG cannot announce a huge image).
void check_png_header(const std::uint8_t* d, std::size_t size, int width, int height, bool depth16,
                      const std::string& source) {
  static const std::uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (size < 33 || std::memcmp(d, kSignature, 8) != 0 || std::memcmp(d + 12, "IHDR", 4) != 0)
    throw InputError(source, "not a PNG image");
  const std::uint32_t w = be32(d + 16), h = be32(d + 20);
  if (w != std::uint32_t(width) || h != std::uint32_t(height))
    throw InputError(
        source, "PNG is " + std::to_string(w) + "x" + std::to_string(h) + ", expected " + size_text(width, height));
  const int bit_depth = d[24], color_type = d[25];
  if (depth16 && (bit_depth != 16 || color_type != 0)) throw InputError(source, "depth PNG must be 16-bit grey");
}

// Bounded work per JPEG: a progressive JPEG may hold thousands of tiny scans, each a pass over
// the whole image. Counts the scans (SOS markers) after the frame header; more than kMaxJpegScans
// is refused. Scan data is skipped byte-wise (0xFF00 stuffing and restart markers stay inside).
constexpr int kMaxJpegScans = 64;
void check_jpeg_scans(const std::uint8_t* d, std::size_t size, std::size_t pos, const std::string& source) {
  int scans = 0;
  while (pos + 1 < size) {
    if (d[pos] != 0xff) {
      ++pos;
      continue;
    }
    const std::uint8_t marker = d[pos + 1];
    if (marker == 0x00 || marker == 0xff || (marker >= 0xd0 && marker <= 0xd7)) {
      ++pos;
      continue;
    }
    if (marker == 0xd9) return;  // end of image
    if (pos + 4 > size) return;
    const std::size_t length = (std::size_t(d[pos + 2]) << 8) | d[pos + 3];
    if (marker == 0xda && ++scans > kMaxJpegScans)
      throw InputError(source, "JPEG has more than " + std::to_string(kMaxJpegScans) + " scans");
    pos += 2 + length;
  }
}

// Finds the JPEG frame header (SOFn) and checks its size before decoding.
void check_jpeg_header(const std::uint8_t* d, std::size_t size, int width, int height, const std::string& source) {
  if (size < 4 || d[0] != 0xff || d[1] != 0xd8) throw InputError(source, "not a JPEG image");
  std::size_t pos = 2;
  while (pos + 4 <= size) {
    if (d[pos] != 0xff) throw InputError(source, "corrupt JPEG: bad marker");
    const std::uint8_t marker = d[pos + 1];
    if (marker == 0xff) {  // fill byte
      ++pos;
      continue;
    }
    if (marker == 0x01 || (marker >= 0xd0 && marker <= 0xd7)) {  // no length
      pos += 2;
      continue;
    }
    const std::size_t length = (std::size_t(d[pos + 2]) << 8) | d[pos + 3];
    if (length < 2 || pos + 2 + length > size) throw InputError(source, "corrupt JPEG: segment past the end");
    const bool sof = marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 && marker != 0xcc;
    if (sof) {
      if (length < 8) throw InputError(source, "corrupt JPEG: short frame header");
      const int h = (d[pos + 5] << 8) | d[pos + 6], w = (d[pos + 7] << 8) | d[pos + 8];
      if (w != width || h != height)
        throw InputError(source, "JPEG is " + size_text(w, h) + ", expected " + size_text(width, height));
      check_jpeg_scans(d, size, pos + 2 + length, source);
      return;
    }
    if (marker == 0xda || marker == 0xd9) break;  // scan or end before a frame header
    pos += 2 + length;
  }
  throw InputError(source, "corrupt JPEG: no frame header");
}

cv::Mat imdecode_checked(const std::uint8_t* data, std::size_t size, int flags, int type, int width, int height,
                         const std::string& source) {
  cv::Mat out;
  try {
    out = image_io().imdecode(cv::Mat(1, int(size), CV_8UC1, const_cast<std::uint8_t*>(data)), flags);
  } catch (const cv::Exception&) {
    throw InputError(source, "image could not be decoded");
  }
  if (out.empty()) throw InputError(source, "image could not be decoded");
  if (out.type() != type || out.cols != width || out.rows != height)
    throw InputError(source, "decoded image is " + size_text(out.cols, out.rows) + " of the wrong type, expected " +
                                 size_text(width, height));
  return out;
}

// A wire PNG whose header says the announced size. The plain images robots send (8-bit RGB,
// 16-bit grey, not interlaced) are inflated once by libdeflate into a buffer of exactly the
// header's size, every CRC, length and the Adler-32 checked (png16_decode.h): bounded by
// construction, as the pre-check is. Anything else, and any damage, goes the guarded way: the
// stream pre-check (png_guard.h), then OpenCV, which reports a damaged file.
cv::Mat decode_png_bounded(const std::uint8_t* data, std::size_t size, int width, int height, bool depth16,
                           const std::string& source) {
  cv::Mat out;
  if (depth16 ? decode_png16_gray(data, size, out) : decode_png_rgb8(data, size, out)) return out;
  check_png_stream(data, size, PngLimits{width, height, depth16}, source);
  return depth16 ? imdecode_checked(data, size, cv::IMREAD_ANYDEPTH, CV_16UC1, width, height, source)
                 : imdecode_checked(data, size, cv::IMREAD_COLOR, CV_8UC3, width, height, source);
}

Bytes imencode_checked(const char* ext, const cv::Mat& image, const std::vector<int>& params) {
  std::vector<std::uint8_t> out;
  if (!image_io().imencode(ext, image, out, params)) throw std::runtime_error(std::string("cannot encode ") + ext);
  return out;
}

Bytes raw_bytes(const cv::Mat& image) {
  const cv::Mat continuous = image.isContinuous() ? image : image.clone();
  const auto* p = continuous.ptr<std::uint8_t>();
  return Bytes(p, p + continuous.total() * continuous.elemSize());
}

}  // namespace

void CodecOptions::validate() const {
  if (jpeg_quality < 1 || jpeg_quality > 100) throw ConfigError("JPEG quality must be in 1..100");
  if (png_compression < 0 || png_compression > 9) throw ConfigError("PNG compression must be in 0..9");
  if (zstd_level < 1 || zstd_level > 19) throw ConfigError("zstd level must be in 1..19");
  if (h264_intra_crf < 0 || h264_intra_crf > 51) throw ConfigError("H.264 intra crf must be in 0..51");
}

const char* to_string(RgbCodec codec) {
  switch (codec) {
    case RgbCodec::kRaw:
      return "raw";
    case RgbCodec::kJpeg:
      return "jpeg";
    case RgbCodec::kPng:
      return "png";
    case RgbCodec::kH264Intra:
      return "h264-intra";
  }
  return "unknown";
}

const char* to_string(DepthCodec codec) {
  switch (codec) {
    case DepthCodec::kRaw:
      return "raw";
    case DepthCodec::kPng:
      return "png";
    case DepthCodec::kRvl:
      return "rvl";
    case DepthCodec::kZstdDelta:
      return "zstd";
  }
  return "unknown";
}

RgbCodec auto_rgb_codec(bool light_frames) { return light_frames ? RgbCodec::kH264Intra : RgbCodec::kJpeg; }

RgbCodec parse_rgb_codec(const std::string& name) {
  for (auto c : {RgbCodec::kRaw, RgbCodec::kJpeg, RgbCodec::kPng, RgbCodec::kH264Intra})
    if (name == to_string(c)) return c;
  throw ConfigError("unknown RGB codec '" + name + "' (raw, jpeg, png, h264-intra)");
}

RgbCodec parse_rgb_codec(const std::string& name, bool light_frames) {
  return name == "auto" ? auto_rgb_codec(light_frames) : parse_rgb_codec(name);
}

DepthCodec parse_depth_codec(const std::string& name) {
  for (auto c : {DepthCodec::kRaw, DepthCodec::kPng, DepthCodec::kRvl, DepthCodec::kZstdDelta})
    if (name == to_string(c)) return c;
  throw ConfigError("unknown depth codec '" + name + "' (raw, png, rvl, zstd)");
}

Bytes encode_rgb(const cv::Mat& bgr, const CodecOptions& options) {
  if (bgr.type() != CV_8UC3 || bgr.empty()) throw std::invalid_argument("encode_rgb: expected a CV_8UC3 image");
  switch (options.rgb) {
    case RgbCodec::kRaw:
      return raw_bytes(bgr);
    case RgbCodec::kJpeg:
      return imencode_checked(".jpg", bgr, {cv::IMWRITE_JPEG_QUALITY, options.jpeg_quality});
    case RgbCodec::kPng:
      return imencode_checked(".png", bgr, {cv::IMWRITE_PNG_COMPRESSION, options.png_compression});
    case RgbCodec::kH264Intra:
      throw std::invalid_argument("encode_rgb: h264-intra pictures come from one ImageEncoder per stream");
  }
  throw std::invalid_argument("encode_rgb: unknown codec");
}

Bytes encode_depth(const cv::Mat& depth, const CodecOptions& options) {
  if (depth.type() != CV_16UC1 || depth.empty()) throw std::invalid_argument("encode_depth: expected a CV_16UC1 image");
  const cv::Mat d = depth.isContinuous() ? depth : depth.clone();
  switch (options.depth) {
    case DepthCodec::kRaw:
      return raw_bytes(d);
    case DepthCodec::kPng:
      return imencode_checked(".png", d, {cv::IMWRITE_PNG_COMPRESSION, options.png_compression});
    case DepthCodec::kRvl:
      return depth_codec::rvl_encode(d.ptr<std::uint16_t>(), d.total());
    case DepthCodec::kZstdDelta:
      return depth_codec::zstd_delta_encode(d.ptr<std::uint16_t>(), d.cols, d.rows, options.zstd_level);
  }
  throw std::invalid_argument("encode_depth: unknown codec");
}

cv::Mat decode_rgb(RgbCodec codec, const std::uint8_t* data, std::size_t size, int width, int height,
                   const std::string& source) {
  check_announced_size(width, height, source);
  switch (codec) {
    case RgbCodec::kRaw: {
      if (size != std::size_t(width) * height * 3)
        throw InputError(source,
                         "raw RGB has " + std::to_string(size) + " bytes, expected " + size_text(width, height) + "x3");
      cv::Mat out(height, width, CV_8UC3);
      std::memcpy(out.data, data, size);
      return out;
    }
    case RgbCodec::kJpeg:
      check_jpeg_header(data, size, width, height, source);
      return decode_jpeg_bgr(data, size, source, width, height);
    case RgbCodec::kPng:
      check_png_header(data, size, width, height, false, source);
      return decode_png_bounded(data, size, width, height, false, source);
    case RgbCodec::kH264Intra: {
      if (width % 2 != 0 || height % 2 != 0)
        throw InputError(source, "H.264 image size " + size_text(width, height) + " is not even");
      if (!video::is_h264_key_packet(data, size)) throw InputError(source, "not a standalone H.264 key picture");
      video::H264Decoder decoder(width, height);
      return decoder.decode(data, size, source);
    }
  }
  throw InputError(source, "unknown RGB encoding");
}

cv::Mat decode_depth(DepthCodec codec, const std::uint8_t* data, std::size_t size, int width, int height,
                     const std::string& source) {
  check_announced_size(width, height, source);
  switch (codec) {
    case DepthCodec::kRaw: {
      if (size != std::size_t(width) * height * 2)
        throw InputError(
            source, "raw depth has " + std::to_string(size) + " bytes, expected " + size_text(width, height) + "x2");
      cv::Mat out(height, width, CV_16UC1);
      std::memcpy(out.data, data, size);
      return out;
    }
    case DepthCodec::kPng:
      check_png_header(data, size, width, height, true, source);
      return decode_png_bounded(data, size, width, height, true, source);
    case DepthCodec::kRvl: {
      cv::Mat out(height, width, CV_16UC1);
      depth_codec::rvl_decode(data, size, out.ptr<std::uint16_t>(), out.total(), source);
      return out;
    }
    case DepthCodec::kZstdDelta: {
      cv::Mat out(height, width, CV_16UC1);
      depth_codec::zstd_delta_decode(data, size, out.ptr<std::uint16_t>(), width, height, source);
      return out;
    }
  }
  throw InputError(source, "unknown depth encoding");
}

}  // namespace cslam
