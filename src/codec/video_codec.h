#pragma once
// Inter-frame H.264 colour codec (libx264 through Debian 12's libavcodec 59; no network code
// here). A robot's colour frames form one stream: exactly one packet out per frame in, at once
// (no B-frames, no lookahead), and the decoder returns each packet's frame at once too.
//
// Packet = our 16-byte header + one H.264 access unit (annex-B; SPS/PPS repeated in-band before
// every IDR, so a decoder can join at any key packet). All header fields little-endian:
//   0  u8[2] magic "H4"
//   2  u8    version (1)
//   3  u8    flags: bit 0 = key (IDR) frame; other bits must be 0
//   4  u32   frame index within the stream: 0 for the first packet, +1 per packet (a forced key
//            frame continues the count; a new encoder starts again at 0 with a key frame)
//   8  u32   bitstream length = packet size - 16
//   12 u32   CRC-32 (zlib's crc32) of bytes 0..11 followed by the bitstream, so a damaged
//            flag or index is caught as well as damaged payload
//
// Encoder settings, all explicit so another client (e.g. Python: python3-opencv for the colour
// conversion, PyAV or libavcodec for the same libx264 build, x264 core 164 on Debian 12) can
// reproduce the same bytes: BGR -> I420 by cv::cvtColor(COLOR_BGR2YUV_I420) (OpenCV's BT.601
// limited range; flagged in the stream's VUI as smpte170m / tv range); libx264 with preset =
// options.preset, tune = options.tune, crf = options.crf, bframes 0, rc-lookahead 0, threads 1
// (deterministic), keyint = options.key_interval, default keyint-min and scenecut, forced-idr 1,
// time base 1/frame_rate with pts = frame index, no global header. Forcing a key frame sets the
// input frame's picture type to I.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include <opencv2/core.hpp>

#include "codec/image_codec.h"

namespace cslam::video {

struct H264Options {
  // Defaults measured with cslam-bench-codec --h264 on every frame of tum_fr1_desk and
  // tum_fr1_rpy: the largest CRF whose PSNR (36.9 / 37.4 dB) stays within 0.3 dB of JPEG q75's
  // (37.0 / 37.7 dB) and which keeps as many ORB features (86.7 / 85.1 % vs 86.6 / 84.8 %), at
  // 20.1 / 19.2 KB per frame against JPEG q75's 36.5 / 33.5 KB.
  int crf = 17;                     // 0..51 (x264 constant rate factor; lower = better, larger)
  std::string preset = "veryfast";  // x264 preset: ultrafast .. placebo
  // x264 tune list; must include zerolatency (no B-frames, no lookahead, no frame delay). At most
  // one of film, animation, grain, stillimage, psnr, ssim may be added (x264 checks this). psnr
  // turns off x264's psychovisual tuning, which adds texture the camera never saw: at equal size
  // +1 dB and more ORB features kept than zerolatency alone (same benchmark).
  std::string tune = "zerolatency,psnr";
  int key_interval = 300;  // frames between automatic IDR frames, 1..100000
  int frame_rate = 30;     // 1..1000; x264's rate control weighs frames by duration
  // Throws ConfigError on an out-of-range value or an unknown preset or tune.
  void validate() const;
};

// The lean stream's light frames (cslam-client --depth-every K; docs/network.md, "Light frames'
// colour"): they are only tracked, never stored, so a coarser stream than the default (CRF 17,
// JPEG q75's PSNR) is 40 % smaller at no measured cost in ATE, and x264's superfast preset
// encodes it in two thirds of veryfast's CPU at a higher PSNR and more ORB features kept, for
// ~1 KB more per frame. The client sends with these; cslam-slam --coded-colour simulates them.
H264Options light_colour_stream();

// Full frames' colour as standalone pictures (RgbCodec::kH264Intra): one encoder per stream with
// these options (ImageEncoder), key interval 1, so every picture is a key packet that decodes on
// its own. superfast as the light frames' stream; the CRF is
// CodecOptions::h264_intra_crf (default 15: smaller than JPEG q75 with more ORB features kept,
// docs/results/bandwidth.md). Throws ConfigError if crf is out of 0..51.
H264Options intra_image(int crf);

constexpr std::size_t kH264HeaderBytes = 16;

// True if the packet has our header (magic, version) with the key flag set. Reads only the
// header: no CRC check, no decoding.
bool is_h264_key_packet(const std::uint8_t* data, std::size_t size);

class H264Encoder {
 public:
  // width and height: even, 2..kMaxImageSide, else ConfigError; options.validate() is called.
  // Throws std::runtime_error if libavcodec has no libx264 encoder or refuses the settings.
  H264Encoder(int width, int height, H264Options options = {});
  ~H264Encoder();
  H264Encoder(const H264Encoder&) = delete;
  H264Encoder& operator=(const H264Encoder&) = delete;

  // bgr: CV_8UC3 of exactly width x height, else std::invalid_argument. Returns the frame's
  // packet (header + access unit). The first packet and every force_key packet are key frames.
  Bytes encode(const cv::Mat& bgr, bool force_key = false);
  // Index the next packet will carry.
  std::uint32_t next_index() const { return next_index_; }

 private:
  struct State;
  std::unique_ptr<State> state_;
  int width_, height_;
  std::uint32_t next_index_ = 0;
};

struct H264DecoderStats {
  std::uint64_t decoded = 0;          // frames returned
  std::uint64_t gaps = 0;             // non-key packet after a missing one: chain broken
  std::uint64_t stale = 0;            // non-key packet at or before the last decoded index: dropped, chain kept
  std::uint64_t corrupt = 0;          // bad header, length, CRC, bitstream or output size: chain broken
  std::uint64_t refused_waiting = 0;  // non-key packet while waiting for a key frame
};

// One decoder per stream (per robot); not thread-safe: use each object from one thread at a time.
class H264Decoder {
 public:
  // The stream must decode to exactly width x height (even, 2..kMaxImageSide, else ConfigError);
  // libavcodec is told the pixel budget, so a stream announcing more fails before allocating it.
  H264Decoder(int width, int height);
  ~H264Decoder();
  H264Decoder(const H264Decoder&) = delete;
  H264Decoder& operator=(const H264Decoder&) = delete;

  // Returns the packet's frame (CV_8UC3 BGR, width x height) or throws InputError(source, ...)
  // saying what is wrong. Chain rule: a key packet always restarts the chain (whatever its
  // index: a restarted encoder begins at 0). A non-key packet decodes only if its index is the
  // last decoded index + 1 and the decoder is not waiting for a key. Index beyond that: gap, the
  // decoder waits for a key. Index at or before it: stale, dropped, chain intact. Corrupt packet:
  // the decoder waits for a key. A new decoder waits for a key.
  cv::Mat decode(const std::uint8_t* data, std::size_t size, const std::string& source);
  bool waiting_for_key() const { return waiting_for_key_; }
  const H264DecoderStats& stats() const { return stats_; }

 private:
  struct State;
  [[noreturn]] void fail_corrupt(const std::string& source, const std::string& message);
  cv::Mat decode_bitstream(const std::uint8_t* data, std::size_t size, const std::string& source);

  std::unique_ptr<State> state_;
  int width_, height_;
  bool waiting_for_key_ = true;
  std::uint32_t last_index_ = 0;
  H264DecoderStats stats_;
};

}  // namespace cslam::video
