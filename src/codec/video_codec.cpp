#include "codec/video_codec.h"

#include <algorithm>
#include <cstdarg>
#include <cstring>
#include <mutex>
#include <new>
#include <stdexcept>
#include <string>

#include <opencv2/imgproc.hpp>
#include <zlib.h>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavutil/dict.h>
#include <libavutil/error.h>
#include <libavutil/frame.h>
#include <libavutil/log.h>
#include <libavutil/pixdesc.h>
}

#include "core/error.h"

namespace cslam::video {

namespace {

constexpr std::uint8_t kMagic0 = 'H', kMagic1 = '4', kVersion = 1, kFlagKey = 1;

struct CodecContextDeleter {
  void operator()(AVCodecContext* c) const { avcodec_free_context(&c); }
};
struct FrameDeleter {
  void operator()(AVFrame* f) const { av_frame_free(&f); }
};
struct PacketDeleter {
  void operator()(AVPacket* p) const { av_packet_free(&p); }
};
struct DictDeleter {
  void operator()(AVDictionary* d) const { av_dict_free(&d); }
};
using CodecContextPtr = std::unique_ptr<AVCodecContext, CodecContextDeleter>;
using FramePtr = std::unique_ptr<AVFrame, FrameDeleter>;
using PacketPtr = std::unique_ptr<AVPacket, PacketDeleter>;

// libav* log lines go nowhere by default here (a hostile stream must not flood stderr, x264's
// banner and statistics are noise); the first error line of this thread is kept for the exception
// text (the first one of a call names the cause; later ones are consequences, e.g. "no frame!").
// This replaces libav's process-wide callback: cslam has no other libav user.
thread_local std::string t_av_error;
void capture_av_log(void* avcl, int level, const char* fmt, va_list vl) {
  if (level > AV_LOG_ERROR || !t_av_error.empty()) return;
  char line[256];
  int print_prefix = 0;
  av_log_format_line2(avcl, level, fmt, vl, line, sizeof line, &print_prefix);
  t_av_error = line;
  while (!t_av_error.empty() && (t_av_error.back() == '\n' || t_av_error.back() == ' ')) t_av_error.pop_back();
}
void install_av_log() {
  static std::once_flag once;
  std::call_once(once, [] { av_log_set_callback(capture_av_log); });
}

std::string av_error_text(int err) {
  char buf[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(err, buf, sizeof buf);
  std::string text = buf;
  if (!t_av_error.empty()) text += " (" + t_av_error + ")";
  return text;
}

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
  CodecContextPtr ctx;
  FramePtr frame;
  PacketPtr packet;
  cv::Mat i420;
};

H264Encoder::H264Encoder(int width, int height, H264Options options)
    : state_(std::make_unique<State>()), width_(width), height_(height) {
  check_size(width, height);
  options.validate();
  install_av_log();
  const AVCodec* codec = avcodec_find_encoder_by_name("libx264");
  if (!codec) throw std::runtime_error("libavcodec has no libx264 encoder");
  state_->ctx.reset(avcodec_alloc_context3(codec));
  state_->frame.reset(av_frame_alloc());
  state_->packet.reset(av_packet_alloc());
  if (!state_->ctx || !state_->frame || !state_->packet) throw std::bad_alloc();
  AVCodecContext* c = state_->ctx.get();
  c->width = width;
  c->height = height;
  c->pix_fmt = AV_PIX_FMT_YUV420P;
  c->color_range = AVCOL_RANGE_MPEG;  // cv::cvtColor's I420 is BT.601 limited range
  c->colorspace = AVCOL_SPC_SMPTE170M;
  c->time_base = AVRational{1, options.frame_rate};
  c->framerate = AVRational{options.frame_rate, 1};
  c->gop_size = options.key_interval;
  c->max_b_frames = 0;
  c->thread_count = 1;  // deterministic output, one core
  // Not AV_CODEC_FLAG_GLOBAL_HEADER: SPS/PPS stay in-band before every IDR.
  AVDictionary* raw_opts = nullptr;
  av_dict_set(&raw_opts, "preset", options.preset.c_str(), 0);
  av_dict_set(&raw_opts, "tune", options.tune.c_str(), 0);
  av_dict_set(&raw_opts, "crf", std::to_string(options.crf).c_str(), 0);
  av_dict_set(&raw_opts, "rc-lookahead", "0", 0);
  av_dict_set(&raw_opts, "forced-idr", "1", 0);
  t_av_error.clear();
  int err = avcodec_open2(c, codec, &raw_opts);
  std::unique_ptr<AVDictionary, DictDeleter> unused(raw_opts);
  if (err < 0) throw std::runtime_error("libx264: cannot open the encoder: " + av_error_text(err));
  if (av_dict_count(unused.get()) > 0)
    throw std::runtime_error(std::string("libx264 ignored option '") +
                             av_dict_get(unused.get(), "", nullptr, AV_DICT_IGNORE_SUFFIX)->key + "'");
  AVFrame* f = state_->frame.get();
  f->format = AV_PIX_FMT_YUV420P;
  f->width = width;
  f->height = height;
  if ((err = av_frame_get_buffer(f, 0)) < 0) throw std::runtime_error("av_frame_get_buffer: " + av_error_text(err));
}

H264Encoder::~H264Encoder() = default;

Bytes H264Encoder::encode(const cv::Mat& bgr, bool force_key) {
  if (bgr.type() != CV_8UC3 || bgr.cols != width_ || bgr.rows != height_)
    throw std::invalid_argument("H264Encoder::encode: expected a CV_8UC3 " + size_text(width_, height_) + " image");
  State& s = *state_;
  t_av_error.clear();
  cv::cvtColor(bgr, s.i420, cv::COLOR_BGR2YUV_I420);  // Y (w x h), then U, V (w/2 x h/2 each)
  AVFrame* f = s.frame.get();
  int err = av_frame_make_writable(f);
  if (err < 0) throw std::runtime_error("av_frame_make_writable: " + av_error_text(err));
  const std::uint8_t* src = s.i420.data;
  const int plane_w[3] = {width_, width_ / 2, width_ / 2}, plane_h[3] = {height_, height_ / 2, height_ / 2};
  for (int p = 0; p < 3; ++p)
    for (int y = 0; y < plane_h[p]; ++y, src += plane_w[p])
      std::memcpy(f->data[p] + std::ptrdiff_t(y) * f->linesize[p], src, std::size_t(plane_w[p]));
  f->pts = next_index_;
  f->pict_type = force_key ? AV_PICTURE_TYPE_I : AV_PICTURE_TYPE_NONE;
  if ((err = avcodec_send_frame(s.ctx.get(), f)) < 0)
    throw std::runtime_error("libx264: send_frame: " + av_error_text(err));
  AVPacket* pkt = s.packet.get();
  if ((err = avcodec_receive_packet(s.ctx.get(), pkt)) < 0)  // zerolatency: never EAGAIN
    throw std::runtime_error("libx264: no packet for the frame: " + av_error_text(err));
  const bool key = (pkt->flags & AV_PKT_FLAG_KEY) != 0;
  Bytes out(kH264HeaderBytes + std::size_t(pkt->size));
  out[0] = kMagic0;
  out[1] = kMagic1;
  out[2] = kVersion;
  out[3] = key ? kFlagKey : 0;
  put_le32(&out[4], next_index_);
  put_le32(&out[8], std::uint32_t(pkt->size));
  std::memcpy(out.data() + kH264HeaderBytes, pkt->data, std::size_t(pkt->size));
  put_le32(&out[12], packet_crc(out.data(), out.data() + kH264HeaderBytes, std::size_t(pkt->size)));
  av_packet_unref(pkt);
  if (avcodec_receive_packet(s.ctx.get(), pkt) != AVERROR(EAGAIN)) {
    av_packet_unref(pkt);
    throw std::logic_error("libx264 returned more than one packet for a frame");
  }
  ++next_index_;
  return out;
}

// ---------------------------------------------------------------------------------------------
struct H264Decoder::State {
  CodecContextPtr ctx;
  FramePtr frame, extra;
  PacketPtr packet;
  cv::Mat i420;
};

H264Decoder::H264Decoder(int width, int height) : state_(std::make_unique<State>()), width_(width), height_(height) {
  check_size(width, height);
  install_av_log();
  const AVCodec* codec = avcodec_find_decoder(AV_CODEC_ID_H264);
  if (!codec) throw std::runtime_error("libavcodec has no H.264 decoder");
  state_->ctx.reset(avcodec_alloc_context3(codec));
  state_->frame.reset(av_frame_alloc());
  state_->extra.reset(av_frame_alloc());
  state_->packet.reset(av_packet_alloc());
  if (!state_->ctx || !state_->frame || !state_->extra || !state_->packet) throw std::bad_alloc();
  AVCodecContext* c = state_->ctx.get();
  c->thread_count = 1;                  // no frame threading: no output delay
  c->flags |= AV_CODEC_FLAG_LOW_DELAY;  // no reordering delay (our streams have no B-frames)
  c->flags &= ~AV_CODEC_FLAG_OUTPUT_CORRUPT;
  c->err_recognition = AV_EF_EXPLODE | AV_EF_BITSTREAM | AV_EF_BUFFER;
  // Pixel budget: the expected size plus libavcodec's alignment and edges (its buffer for
  // 160x120 is checked as 192x120). A stream announcing a larger picture fails in libavcodec's
  // size check before anything of that size is allocated; the exact size is checked after.
  c->max_pixels = std::int64_t(((width + 15) & ~15) + 64) * (((height + 15) & ~15) + 64);
  c->width = width;
  c->height = height;
  t_av_error.clear();
  const int err = avcodec_open2(c, codec, nullptr);
  if (err < 0) throw std::runtime_error("cannot open the H.264 decoder: " + av_error_text(err));
  state_->i420.create(height * 3 / 2, width, CV_8UC1);
}

H264Decoder::~H264Decoder() = default;

void H264Decoder::fail_corrupt(const std::string& source, const std::string& message) {
  ++stats_.corrupt;
  waiting_for_key_ = true;
  avcodec_flush_buffers(state_->ctx.get());
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
      avcodec_flush_buffers(state_->ctx.get());
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
  AVCodecContext* c = s.ctx.get();
  AVPacket* pkt = s.packet.get();
  AVFrame* f = s.frame.get();
  t_av_error.clear();
  // Not reference-counted: avcodec_send_packet copies the bytes into a padded buffer.
  pkt->data = const_cast<std::uint8_t*>(data);
  pkt->size = int(size);
  int err = avcodec_send_packet(c, pkt);
  pkt->data = nullptr;
  pkt->size = 0;
  if (err < 0) fail_corrupt(source, "libavcodec: " + av_error_text(err));
  if ((err = avcodec_receive_frame(c, f)) < 0)
    fail_corrupt(source, err == AVERROR(EAGAIN) ? "no picture decoded" : "libavcodec: " + av_error_text(err));
  struct Unref {
    AVFrame* f;
    ~Unref() { av_frame_unref(f); }
  } unref{f};
  if (f->width != width_ || f->height != height_)
    fail_corrupt(source, "picture is " + size_text(f->width, f->height) + ", expected " + size_text(width_, height_));
  if (f->format != AV_PIX_FMT_YUV420P) {
    const char* name = av_get_pix_fmt_name(AVPixelFormat(f->format));
    fail_corrupt(source, std::string("pixel format ") + (name ? name : "unknown") + ", expected yuv420p");
  }
  if ((f->flags & AV_FRAME_FLAG_CORRUPT) || f->decode_error_flags)
    fail_corrupt(source, "libavcodec reports a damaged picture");
  const int more = avcodec_receive_frame(c, s.extra.get());
  av_frame_unref(s.extra.get());
  if (more != AVERROR(EAGAIN)) fail_corrupt(source, "more than one picture in the packet");
  std::uint8_t* dst = s.i420.data;
  const int plane_w[3] = {width_, width_ / 2, width_ / 2}, plane_h[3] = {height_, height_ / 2, height_ / 2};
  for (int p = 0; p < 3; ++p)
    for (int y = 0; y < plane_h[p]; ++y, dst += plane_w[p])
      std::memcpy(dst, f->data[p] + std::ptrdiff_t(y) * f->linesize[p], std::size_t(plane_w[p]));
  cv::Mat bgr;
  cv::cvtColor(s.i420, bgr, cv::COLOR_YUV2BGR_I420);
  return bgr;
}

}  // namespace cslam::video
