// Plugin: libavcodec's H.264 (libx264 encoder, libavcodec's decoder) behind codec_plugins.h's
// H264Api, loaded on first use. The packet format, the chain rules and the colour conversion are
// video_codec.cpp's; this file only moves I420 pictures in and out of libavcodec.
#include <cstdarg>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>
#include <stdexcept>
#include <string>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavutil/dict.h>
#include <libavutil/error.h>
#include <libavutil/frame.h>
#include <libavutil/log.h>
#include <libavutil/pixdesc.h>
}

#include "codec/codec_plugins.h"
#include "codec/video_codec.h"

namespace {

using cslam::video::H264Options;

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

// The three planes of an I420 image (Y w x h, then U and V w/2 x h/2, contiguous) into an
// AVFrame's (into_frame) or out of it.
void copy_planes(std::uint8_t* i420, AVFrame* f, int w, int h, bool into_frame) {
  const int plane_w[3] = {w, w / 2, w / 2}, plane_h[3] = {h, h / 2, h / 2};
  for (int p = 0; p < 3; ++p)
    for (int y = 0; y < plane_h[p]; ++y, i420 += plane_w[p]) {
      std::uint8_t* row = f->data[p] + std::ptrdiff_t(y) * f->linesize[p];
      if (into_frame)
        std::memcpy(row, i420, std::size_t(plane_w[p]));
      else
        std::memcpy(i420, row, std::size_t(plane_w[p]));
    }
}

class Encoder final : public cslam::video::H264EncoderEngine {
 public:
  Encoder(int width, int height, const H264Options& options) : width_(width), height_(height) {
    install_av_log();
    const AVCodec* codec = avcodec_find_encoder_by_name("libx264");
    if (!codec) throw std::runtime_error("libavcodec has no libx264 encoder");
    ctx_.reset(avcodec_alloc_context3(codec));
    frame_.reset(av_frame_alloc());
    packet_.reset(av_packet_alloc());
    if (!ctx_ || !frame_ || !packet_) throw std::bad_alloc();
    AVCodecContext* c = ctx_.get();
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
    AVFrame* f = frame_.get();
    f->format = AV_PIX_FMT_YUV420P;
    f->width = width;
    f->height = height;
    if ((err = av_frame_get_buffer(f, 0)) < 0) throw std::runtime_error("av_frame_get_buffer: " + av_error_text(err));
  }

  void encode(const cv::Mat& i420, std::int64_t pts, bool force_key, std::vector<std::uint8_t>& out,
              bool& key) override {
    t_av_error.clear();
    AVFrame* f = frame_.get();
    int err = av_frame_make_writable(f);
    if (err < 0) throw std::runtime_error("av_frame_make_writable: " + av_error_text(err));
    copy_planes(i420.data, f, width_, height_, true);
    f->pts = pts;
    f->pict_type = force_key ? AV_PICTURE_TYPE_I : AV_PICTURE_TYPE_NONE;
    if ((err = avcodec_send_frame(ctx_.get(), f)) < 0)
      throw std::runtime_error("libx264: send_frame: " + av_error_text(err));
    AVPacket* pkt = packet_.get();
    if ((err = avcodec_receive_packet(ctx_.get(), pkt)) < 0)  // zerolatency: never EAGAIN
      throw std::runtime_error("libx264: no packet for the frame: " + av_error_text(err));
    key = (pkt->flags & AV_PKT_FLAG_KEY) != 0;
    out.insert(out.end(), pkt->data, pkt->data + pkt->size);
    av_packet_unref(pkt);
    if (avcodec_receive_packet(ctx_.get(), pkt) != AVERROR(EAGAIN)) {
      av_packet_unref(pkt);
      throw std::logic_error("libx264 returned more than one packet for a frame");
    }
  }

 private:
  int width_, height_;
  CodecContextPtr ctx_;
  FramePtr frame_;
  PacketPtr packet_;
};

class Decoder final : public cslam::video::H264DecoderEngine {
 public:
  Decoder(int width, int height) : width_(width), height_(height) {
    install_av_log();
    const AVCodec* codec = avcodec_find_decoder(AV_CODEC_ID_H264);
    if (!codec) throw std::runtime_error("libavcodec has no H.264 decoder");
    ctx_.reset(avcodec_alloc_context3(codec));
    frame_.reset(av_frame_alloc());
    extra_.reset(av_frame_alloc());
    packet_.reset(av_packet_alloc());
    if (!ctx_ || !frame_ || !extra_ || !packet_) throw std::bad_alloc();
    AVCodecContext* c = ctx_.get();
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
  }

  std::string decode(const std::uint8_t* data, std::size_t size, cv::Mat& i420) override {
    AVCodecContext* c = ctx_.get();
    AVPacket* pkt = packet_.get();
    AVFrame* f = frame_.get();
    t_av_error.clear();
    // Not reference-counted: avcodec_send_packet copies the bytes into a padded buffer.
    pkt->data = const_cast<std::uint8_t*>(data);
    pkt->size = int(size);
    int err = avcodec_send_packet(c, pkt);
    pkt->data = nullptr;
    pkt->size = 0;
    if (err < 0) return "libavcodec: " + av_error_text(err);
    if ((err = avcodec_receive_frame(c, f)) < 0)
      return err == AVERROR(EAGAIN) ? "no picture decoded" : "libavcodec: " + av_error_text(err);
    struct Unref {
      AVFrame* f;
      ~Unref() { av_frame_unref(f); }
    } unref{f};
    if (f->width != width_ || f->height != height_)
      return "picture is " + std::to_string(f->width) + "x" + std::to_string(f->height) + ", expected " +
             std::to_string(width_) + "x" + std::to_string(height_);
    if (f->format != AV_PIX_FMT_YUV420P) {
      const char* name = av_get_pix_fmt_name(AVPixelFormat(f->format));
      return std::string("pixel format ") + (name ? name : "unknown") + ", expected yuv420p";
    }
    if ((f->flags & AV_FRAME_FLAG_CORRUPT) || f->decode_error_flags) return "libavcodec reports a damaged picture";
    const int more = avcodec_receive_frame(c, extra_.get());
    av_frame_unref(extra_.get());
    if (more != AVERROR(EAGAIN)) return "more than one picture in the packet";
    copy_planes(i420.data, f, width_, height_, false);
    return {};
  }

  void flush() override { avcodec_flush_buffers(ctx_.get()); }

 private:
  int width_, height_;
  CodecContextPtr ctx_;
  FramePtr frame_, extra_;
  PacketPtr packet_;
};

cslam::video::H264EncoderEngine* make_encoder(int width, int height, const H264Options& options) {
  return new Encoder(width, height, options);
}
cslam::video::H264DecoderEngine* make_decoder(int width, int height) { return new Decoder(width, height); }

const cslam::video::H264Api kApi{make_encoder, make_decoder};

}  // namespace

extern "C" __attribute__((visibility("default"))) const void* cslam_h264_api() { return &kApi; }
