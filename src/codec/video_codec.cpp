#include "codec/video_codec.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

#include <opencv2/imgproc.hpp>
#include <zlib.h>

#include "codec/codec_plugins.h"
#include "core/error.h"

namespace cslam::video {

namespace {

constexpr std::uint8_t kMagic0 = 'H', kMagic1 = '4', kVersion = 1, kFlagKey = 1;

std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

void check_size(int width, int height) {
  if (width < 2 || height < 2 || width > kMaxImageSide || height > kMaxImageSide || width % 2 || height % 2)
    throw ConfigError("H.264 image size " + size_text(width, height) + ": sides must be even, 2.." +
                      std::to_string(kMaxImageSide));
}

void put_le32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = std::uint8_t(v >> (8 * i));
}
std::uint32_t get_le32(const std::uint8_t* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}

// CRC-32 of header bytes 0..11, then the bitstream.
std::uint32_t packet_crc(const std::uint8_t* header, const std::uint8_t* bitstream, std::size_t length) {
  uLong crc = crc32(0L, header, 12);
  while (length > 0) {  // zlib's crc32 takes a uInt length
    const uInt chunk = uInt(std::min<std::size_t>(length, 1u << 30));
    crc = crc32(crc, bitstream, chunk);
    bitstream += chunk;
    length -= chunk;
  }
  return std::uint32_t(crc);
}

// Largest bitstream we accept for one frame: H.264 cannot need much more than raw 4:2:0 (PCM
// macroblocks) plus headers.
std::size_t max_bitstream_bytes(int width, int height) { return std::size_t(width) * std::size_t(height) * 2 + 65536; }

}  // namespace

H264Options light_colour_stream() {
  H264Options o;
  o.crf = 26;
  o.preset = "superfast";
  return o;
}

H264Options intra_image(int crf) {
  H264Options o;
  o.crf = crf;
  o.preset = "superfast";
  o.key_interval = 1;
  o.validate();
  return o;
}

void H264Options::validate() const {
  static const char* const kPresets[] = {"ultrafast", "superfast", "veryfast", "faster",   "fast",
                                         "medium",    "slow",      "slower",   "veryslow", "placebo"};
  if (crf < 0 || crf > 51) throw ConfigError("h264 crf " + std::to_string(crf) + " out of range 0..51");
  if (std::none_of(std::begin(kPresets), std::end(kPresets), [&](const char* p) { return preset == p; }))
    throw ConfigError("unknown h264 preset '" + preset + "' (ultrafast .. placebo)");
  static const char* const kTunes[] = {"zerolatency", "film", "animation", "grain",
                                       "stillimage",  "psnr", "ssim",      "fastdecode"};
  bool zerolatency = false;
  for (std::size_t p = 0; p <= tune.size();) {
    const std::size_t c = std::min(tune.find(',', p), tune.size());
    const std::string item = tune.substr(p, c - p);
    if (std::none_of(std::begin(kTunes), std::end(kTunes), [&](const char* t) { return item == t; }))
      throw ConfigError("unknown h264 tune '" + item + "' in '" + tune + "'");
    zerolatency |= item == "zerolatency";
    p = c + 1;
  }
  if (!zerolatency) throw ConfigError("h264 tune '" + tune + "' must include zerolatency (one packet per frame)");
  if (key_interval < 1 || key_interval > 100000)
    throw ConfigError("h264 key interval " + std::to_string(key_interval) + " out of range 1..100000");
  if (frame_rate < 1 || frame_rate > 1000)
    throw ConfigError("h264 frame rate " + std::to_string(frame_rate) + " out of range 1..1000");
}

bool is_h264_key_packet(const std::uint8_t* data, std::size_t size) {
  return size >= kH264HeaderBytes && data[0] == kMagic0 && data[1] == kMagic1 && data[2] == kVersion &&
         (data[3] & kFlagKey) != 0;
}

// ---------------------------------------------------------------------------------------------
struct H264Encoder::State {
  std::unique_ptr<H264EncoderEngine> engine;  // libavcodec's side (codec_plugins.h)
  cv::Mat i420;
};

H264Encoder::H264Encoder(int width, int height, H264Options options)
    : state_(std::make_unique<State>()), width_(width), height_(height) {
  check_size(width, height);
  options.validate();
  state_->engine.reset(h264_engine().make_encoder(width, height, options));
}

H264Encoder::~H264Encoder() = default;

Bytes H264Encoder::encode(const cv::Mat& bgr, bool force_key) {
  if (bgr.type() != CV_8UC3 || bgr.cols != width_ || bgr.rows != height_)
    throw std::invalid_argument("H264Encoder::encode: expected a CV_8UC3 " + size_text(width_, height_) + " image");
  State& s = *state_;
  cv::cvtColor(bgr, s.i420, cv::COLOR_BGR2YUV_I420);  // Y (w x h), then U, V (w/2 x h/2 each)
  bool key = false;
  Bytes out(kH264HeaderBytes);  // the engine appends the access unit
  s.engine->encode(s.i420, next_index_, force_key, out, key);
  const std::size_t unit_size = out.size() - kH264HeaderBytes;
  out[0] = kMagic0;
  out[1] = kMagic1;
  out[2] = kVersion;
  out[3] = key ? kFlagKey : 0;
  put_le32(&out[4], next_index_);
  put_le32(&out[8], std::uint32_t(unit_size));
  put_le32(&out[12], packet_crc(out.data(), out.data() + kH264HeaderBytes, unit_size));
  ++next_index_;
  return out;
}

// ---------------------------------------------------------------------------------------------
struct H264Decoder::State {
  std::unique_ptr<H264DecoderEngine> engine;  // libavcodec's side (codec_plugins.h)
  cv::Mat i420;
};

H264Decoder::H264Decoder(int width, int height) : state_(std::make_unique<State>()), width_(width), height_(height) {
  check_size(width, height);
  state_->engine.reset(h264_engine().make_decoder(width, height));
  state_->i420.create(height * 3 / 2, width, CV_8UC1);
}

H264Decoder::~H264Decoder() = default;

void H264Decoder::fail_corrupt(const std::string& source, const std::string& message) {
  ++stats_.corrupt;
  waiting_for_key_ = true;
  state_->engine->flush();
  throw InputError(source, "H.264 packet: " + message);
}

cv::Mat H264Decoder::decode(const std::uint8_t* data, std::size_t size, const std::string& source) {
  if (size < kH264HeaderBytes)
    fail_corrupt(source,
                 "truncated: " + std::to_string(size) + " bytes, header is " + std::to_string(kH264HeaderBytes));
  if (data[0] != kMagic0 || data[1] != kMagic1) fail_corrupt(source, "bad magic");
  if (data[2] != kVersion) fail_corrupt(source, "unsupported version " + std::to_string(data[2]));
  if (data[3] & ~kFlagKey) fail_corrupt(source, "unknown flags " + std::to_string(data[3]));
  const bool key = (data[3] & kFlagKey) != 0;
  const std::uint32_t index = get_le32(data + 4), length = get_le32(data + 8);
  if (length > max_bitstream_bytes(width_, height_))
    fail_corrupt(source,
                 "bitstream length " + std::to_string(length) + " exceeds the limit for " + size_text(width_, height_));
  if (std::size_t(length) != size - kH264HeaderBytes)
    fail_corrupt(source, "bitstream length " + std::to_string(length) + " but " +
                             std::to_string(size - kH264HeaderBytes) + " bytes follow the header");
  if (length == 0) fail_corrupt(source, "empty bitstream");
  if (packet_crc(data, data + kH264HeaderBytes, length) != get_le32(data + 12)) fail_corrupt(source, "CRC mismatch");
  const std::string at = "frame " + std::to_string(index);
  if (!key) {
    if (waiting_for_key_) {
      ++stats_.refused_waiting;
      throw InputError(source, "H.264 " + at + " refused: waiting for a key frame");
    }
    if (std::uint64_t(index) <= last_index_) {
      ++stats_.stale;
      throw InputError(source, "H.264 " + at + " is stale (last decoded " + std::to_string(last_index_) + "), dropped");
    }
    if (std::uint64_t(index) > std::uint64_t(last_index_) + 1) {
      ++stats_.gaps;
      waiting_for_key_ = true;
      state_->engine->flush();
      throw InputError(source, "H.264 " + at + " after " + std::to_string(last_index_) + ": " +
                                   std::to_string(index - last_index_ - 1) + " missing, waiting for a key frame");
    }
  }
  cv::Mat bgr = decode_bitstream(data + kH264HeaderBytes, length, source + " " + at);
  last_index_ = index;
  waiting_for_key_ = false;
  ++stats_.decoded;
  return bgr;
}

cv::Mat H264Decoder::decode_bitstream(const std::uint8_t* data, std::size_t size, const std::string& source) {
  State& s = *state_;
  const std::string problem = s.engine->decode(data, size, s.i420);
  if (!problem.empty()) fail_corrupt(source, problem);
  cv::Mat bgr;
  cv::cvtColor(s.i420, bgr, cv::COLOR_YUV2BGR_I420);
  return bgr;
}

}  // namespace cslam::video
