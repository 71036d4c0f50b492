#include "proto/adapter.h"

#include "codec/depth_subsample.h"
#include "codec/video_codec.h"

#include <cmath>
#include <exception>

#include <opencv2/core/utility.hpp>

namespace cslam::wire {

namespace {

bool rgb_codec_from_wire(Encoding e, RgbCodec* out) {
  switch (e) {
    case RGB_RAW_BGR8:
      *out = RgbCodec::kRaw;
      return true;
    case RGB_JPEG:
      *out = RgbCodec::kJpeg;
      return true;
    case RGB_PNG:
      *out = RgbCodec::kPng;
      return true;
    case RGB_H264_INTRA:
      *out = RgbCodec::kH264Intra;
      return true;
    default:
      return false;
  }
}

bool depth_codec_from_wire(Encoding e, DepthCodec* out) {
  switch (e) {
    case DEPTH_RAW_U16LE:
      *out = DepthCodec::kRaw;
      return true;
    case DEPTH_PNG16:
      *out = DepthCodec::kPng;
      return true;
    case DEPTH_RVL:
      *out = DepthCodec::kRvl;
      return true;
    case DEPTH_ZSTD_DELTA:
      *out = DepthCodec::kZstdDelta;
      return true;
    default:
      return false;
  }
}

void check_size(const Image& image, const PinholeCamera& camera, const char* what, const std::string& source) {
  if (image.width() != std::uint32_t(camera.width) || image.height() != std::uint32_t(camera.height))
    throw WireError(ERROR_SIZE_MISMATCH, source,
                    std::string(what) + " image is " + std::to_string(image.width()) + "x" +
                        std::to_string(image.height()) + " but the hello announced " + std::to_string(camera.width) +
                        "x" + std::to_string(camera.height));
}

}  // namespace

ClientInfo from_hello(const Hello& hello, const std::string& source, std::uint64_t max_pixels) {
  if (hello.version() != kProtocolVersion)
    throw WireError(ERROR_BAD_VERSION, source, version_mismatch_text(hello.version()));
  if (hello.client_id() > 0xffff) throw WireError(ERROR_BAD_HELLO, source, "client id above 65535");
  if (!hello.has_camera()) throw WireError(ERROR_BAD_HELLO, source, "hello without camera");
  const CameraIntrinsics& c = hello.camera();
  if (c.distortion_size() != 0 && c.distortion_size() != 5)
    throw WireError(ERROR_BAD_HELLO, source, "distortion must have 0 or 5 coefficients");
  if (c.width() == 0 || c.height() == 0 || c.width() > std::uint32_t(kMaxImageSide) ||
      c.height() > std::uint32_t(kMaxImageSide))
    throw WireError(ERROR_BAD_HELLO, source, "camera size out of range");
  if (std::uint64_t(c.width()) * c.height() > max_pixels)
    throw WireError(ERROR_BAD_HELLO, source,
                    "camera " + std::to_string(c.width()) + "x" + std::to_string(c.height()) + " has more than " +
                        std::to_string(max_pixels) + " pixels (server --max-pixels)");
  ClientInfo info;
  info.id = ClientId(hello.client_id());
  info.name = hello.name();
  PinholeCamera& cam = info.camera;
  cam.fx = c.fx();
  cam.fy = c.fy();
  cam.cx = c.cx();
  cam.cy = c.cy();
  for (int i = 0; i < c.distortion_size(); ++i) cam.dist[std::size_t(i)] = c.distortion(i);
  cam.width = int(c.width());
  cam.height = int(c.height());
  cam.depth_factor = c.depth_factor();
  cam.depth_scale_correction = c.depth_scale_correction() == 0.0 ? 1.0 : c.depth_scale_correction();
  cam.readout_time = c.readout_time();  // 0 (global shutter) from peers that do not send it
  cam.name = c.name().empty() ? "client" + std::to_string(info.id) : c.name();
  for (double d : cam.dist)
    if (!std::isfinite(d)) throw WireError(ERROR_BAD_HELLO, source, "non-finite distortion coefficient");
  try {
    cam.validate();
  } catch (const std::exception& e) {
    throw WireError(ERROR_BAD_HELLO, source, std::string("invalid camera: ") + e.what());
  }
  return info;
}

namespace {

// The depth image's subsampling (1: full image), after check_frame accepted the frame.
int depth_subsample_of(const RgbdFrame& frame) { return std::max<int>(1, int(frame.depth_subsample())); }

}  // namespace

void check_frame(const RgbdFrame& frame, const PinholeCamera& camera, const std::string& source) {
  RgbCodec rgb_codec;
  DepthCodec depth_codec;
  if (!frame.has_rgb()) throw WireError(ERROR_MALFORMED, source, "frame without a colour image");
  const bool inter_coded = frame.rgb().encoding() == RGB_H264;
  if (!inter_coded && !rgb_codec_from_wire(frame.rgb().encoding(), &rgb_codec))
    throw WireError(ERROR_UNKNOWN_ENCODING, source,
                    "unknown RGB encoding " + std::to_string(int(frame.rgb().encoding())));
  check_size(frame.rgb(), camera, "RGB", source);
  if (frame.depth_subsample() > std::uint32_t(kMaxDepthSubsample))
    throw WireError(ERROR_MALFORMED, source,
                    "depth_subsample " + std::to_string(frame.depth_subsample()) + " is not 0.." +
                        std::to_string(kMaxDepthSubsample));
  if (!frame.has_depth()) {
    if (frame.depth_subsample() > 1) throw WireError(ERROR_MALFORMED, source, "depth_subsample without a depth image");
  } else {
    if (!depth_codec_from_wire(frame.depth().encoding(), &depth_codec))
      throw WireError(ERROR_UNKNOWN_ENCODING, source,
                      "unknown depth encoding " + std::to_string(int(frame.depth().encoding())));
    const int s = depth_subsample_of(frame);
    if (s == 1 && inter_coded)
      throw WireError(ERROR_MALFORMED, source,
                      "a frame with full depth may become a keyframe, so its colour must decode on its own (JPEG, PNG, "
                      "H.264 intra or raw), not as an inter-coded (RGB_H264) packet");
    if (s == 1) {
      check_size(frame.depth(), camera, "depth", source);
    } else {
      const cv::Size size = subsampled_depth_size(camera.width, camera.height, s);
      if (frame.depth().width() != std::uint32_t(size.width) || frame.depth().height() != std::uint32_t(size.height))
        throw WireError(ERROR_SIZE_MISMATCH, source,
                        "depth image subsampled by " + std::to_string(s) + " is " +
                            std::to_string(frame.depth().width()) + "x" + std::to_string(frame.depth().height()) +
                            ", not " + std::to_string(size.width) + "x" + std::to_string(size.height));
    }
  }
  if (!std::isfinite(frame.timestamp())) throw WireError(ERROR_MALFORMED, source, "non-finite timestamp");
  if (!std::isfinite(frame.depth_time_offset()) || std::abs(frame.depth_time_offset()) > kMaxDepthTimeOffset)
    throw WireError(ERROR_MALFORMED, source,
                    "depth_time_offset " + std::to_string(frame.depth_time_offset()) + " s is not within +-" +
                        std::to_string(kMaxDepthTimeOffset) + " s");
}

bool keyframe_eligible(const RgbdFrame& frame) {
  return frame.has_depth() && depth_subsample_of(frame) == 1 && frame.rgb().encoding() != RGB_H264;
}

EncodedRgbd take_encoded(RgbdFrame& frame) {
  EncodedRgbd e;
  if (!rgb_codec_from_wire(frame.rgb().encoding(), &e.rgb_codec) ||
      !depth_codec_from_wire(frame.depth().encoding(), &e.depth_codec))
    throw std::invalid_argument("take_encoded: a frame with unknown encodings");
  e.rgb = std::move(*frame.mutable_rgb()->mutable_data());
  e.depth = std::move(*frame.mutable_depth()->mutable_data());
  return e;
}

cslam::RgbdFrame from_wire_frame(const RgbdFrame& frame, const PinholeCamera& camera, const std::string& source,
                                 video::H264Decoder* colour_stream) {
  check_frame(frame, camera, source);
  const bool inter_coded = frame.rgb().encoding() == RGB_H264;
  if (inter_coded && !colour_stream)
    throw WireError(ERROR_UNKNOWN_ENCODING, source, "inter-coded colour (RGB_H264) is not accepted on this path");
  RgbCodec rgb_codec = RgbCodec::kRaw;
  DepthCodec depth_codec = DepthCodec::kRaw;
  if (!inter_coded) rgb_codec_from_wire(frame.rgb().encoding(), &rgb_codec);
  if (frame.has_depth()) depth_codec_from_wire(frame.depth().encoding(), &depth_codec);
  const int subsample = frame.has_depth() ? depth_subsample_of(frame) : 1;
  const cv::Size depth_size = subsampled_depth_size(camera.width, camera.height, subsample);
  cslam::RgbdFrame out;
  out.client = ClientId(frame.client_id());
  out.seq = frame.seq();
  out.timestamp = frame.timestamp();
  out.depth_time_offset = frame.has_depth() ? frame.depth_time_offset() : 0.0;
  out.depth_subsample = subsample;
  out.live = frame.live();
  const std::string& rgb = frame.rgb().data();
  const std::string& depth = frame.depth().data();
  // RGB and depth decode in parallel (OpenCV's thread pool): about half the latency per frame.
  std::exception_ptr errors[2];
  cv::parallel_for_(cv::Range(0, 2), [&](const cv::Range& range) {
    for (int task = range.start; task < range.end; ++task) {
      try {
        if (task == 0 && inter_coded) {
          out.bgr =
              colour_stream->decode(reinterpret_cast<const std::uint8_t*>(rgb.data()), rgb.size(), source + " rgb");
        } else if (task == 0) {
          out.bgr = decode_rgb(rgb_codec, reinterpret_cast<const std::uint8_t*>(rgb.data()), rgb.size(), camera.width,
                               camera.height, source + " rgb");
        } else if (frame.has_depth()) {
          out.depth = decode_depth(depth_codec, reinterpret_cast<const std::uint8_t*>(depth.data()), depth.size(),
                                   depth_size.width, depth_size.height, source + " depth");
          if (subsample > 1) out.depth = expand_depth(out.depth, subsample, camera.width, camera.height);
        }
      } catch (...) {
        errors[task] = std::current_exception();
      }
    }
  });
  for (int task = 0; task < 2; ++task) {
    if (!errors[task]) continue;
    try {
      std::rethrow_exception(errors[task]);
    } catch (const WireError&) {
      throw;
    } catch (const InputError& e) {
      // A colour packet the stream could not take leaves it without its reference: the robot
      // must send a key packet (ERROR_STREAM_GAP).
      const bool gap = task == 0 && inter_coded && colour_stream->waiting_for_key();
      throw WireError(gap ? ERROR_STREAM_GAP : ERROR_CORRUPT_IMAGE, e.source(), e.what());
    }
  }
  if (out.bgr.cols != camera.width || out.bgr.rows != camera.height)
    throw WireError(ERROR_SIZE_MISMATCH, source, "decoded colour is not the camera's size");
  return out;
}

}  // namespace cslam::wire
