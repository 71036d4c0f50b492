#include "proto/wire.h"

#include <cstdint>

#include "codec/depth_subsample.h"

namespace cslam::wire {

Encoding to_wire(RgbCodec codec) {
  switch (codec) {
    case RgbCodec::kRaw:
      return RGB_RAW_BGR8;
    case RgbCodec::kJpeg:
      return RGB_JPEG;
    case RgbCodec::kPng:
      return RGB_PNG;
    case RgbCodec::kH264Intra:
      return RGB_H264_INTRA;
  }
  return ENCODING_UNSPECIFIED;
}

Encoding to_wire(DepthCodec codec) {
  switch (codec) {
    case DepthCodec::kRaw:
      return DEPTH_RAW_U16LE;
    case DepthCodec::kPng:
      return DEPTH_PNG16;
    case DepthCodec::kRvl:
      return DEPTH_RVL;
    case DepthCodec::kZstdDelta:
      return DEPTH_ZSTD_DELTA;
  }
  return ENCODING_UNSPECIFIED;
}

std::string version_mismatch_text(int peer_version) {
  std::string text = "protocol version " + std::to_string(peer_version) +
                     " is not supported: this server speaks version " + std::to_string(int(kProtocolVersion));
  if (peer_version >= 1 && peer_version < int(kProtocolVersion))
    text += " (since version 2 every ack carries the frame's pose); update the client to this cslam release";
  else if (peer_version == 0)
    text += " (the hello carries no version: not a cslam client?)";
  else
    text += "; the client is newer than this server: update the server";
  return text;
}

Hello to_hello(const ClientInfo& info) {
  Hello h;
  h.set_version(kProtocolVersion);
  h.set_client_id(info.id);
  h.set_name(info.name);
  CameraIntrinsics* c = h.mutable_camera();
  const PinholeCamera& cam = info.camera;
  c->set_fx(cam.fx);
  c->set_fy(cam.fy);
  c->set_cx(cam.cx);
  c->set_cy(cam.cy);
  for (double d : cam.dist) c->add_distortion(d);
  c->set_width(std::uint32_t(cam.width));
  c->set_height(std::uint32_t(cam.height));
  c->set_depth_factor(cam.depth_factor);
  c->set_depth_scale_correction(cam.depth_scale_correction);
  c->set_name(cam.name);
  c->set_readout_time(cam.readout_time);
  return h;
}

bool to_wire_frame(const cslam::RgbdFrame& frame, ImageEncoder& images, RgbdFrame* out, const ByteBudget* budget) {
  const CodecOptions& options = images.options();
  out->set_client_id(frame.client);
  out->set_seq(frame.seq);
  out->set_timestamp(frame.timestamp);
  out->set_depth_time_offset(frame.depth_time_offset);
  out->set_live(frame.live);
  const Bytes depth = images.depth(frame.depth);
  const EncodedRgb rgb = images.full_colour(frame.bgr, budget, depth.size());
  Image* r = out->mutable_rgb();
  r->set_width(std::uint32_t(frame.bgr.cols));
  r->set_height(std::uint32_t(frame.bgr.rows));
  r->set_encoding(to_wire(rgb.codec));
  r->set_data(rgb.bytes.data(), rgb.bytes.size());
  Image* d = out->mutable_depth();
  d->set_width(std::uint32_t(frame.depth.cols));
  d->set_height(std::uint32_t(frame.depth.rows));
  d->set_encoding(to_wire(options.depth));
  d->set_data(depth.data(), depth.size());
  return rgb.finer;
}

void to_wire_light_frame(const cslam::RgbdFrame& frame, const Bytes& colour_packet, int depth_subsample,
                         const CodecOptions& options, RgbdFrame* out) {
  out->set_client_id(frame.client);
  out->set_seq(frame.seq);
  out->set_timestamp(frame.timestamp);
  out->set_live(frame.live);
  Image* r = out->mutable_rgb();
  r->set_width(std::uint32_t(frame.bgr.cols));
  r->set_height(std::uint32_t(frame.bgr.rows));
  r->set_encoding(RGB_H264);
  r->set_data(colour_packet.data(), colour_packet.size());
  if (depth_subsample < 2 || frame.depth.empty()) {
    out->clear_depth();
    out->set_depth_subsample(0);
    out->set_depth_time_offset(0);
    return;
  }
  const cv::Mat coarse = subsample_depth(frame.depth, depth_subsample);
  const Bytes depth = encode_depth(coarse, options);
  Image* d = out->mutable_depth();
  d->set_width(std::uint32_t(coarse.cols));
  d->set_height(std::uint32_t(coarse.rows));
  d->set_encoding(to_wire(options.depth));
  d->set_data(depth.data(), depth.size());
  out->set_depth_subsample(std::uint32_t(depth_subsample));
  out->set_depth_time_offset(frame.depth_time_offset);
}

ClientMessage parse_client_message(const void* data, std::size_t size, const std::string& source) {
  ClientMessage m;
  if (size > std::size_t(INT32_MAX) || !m.ParseFromArray(data, int(size)))
    throw WireError(ERROR_MALFORMED, source, "not a cslam ClientMessage (" + std::to_string(size) + " bytes)");
  if (m.body_case() == ClientMessage::BODY_NOT_SET)
    throw WireError(ERROR_MALFORMED, source, "ClientMessage without body");
  return m;
}

ServerMessage parse_server_message(const void* data, std::size_t size, const std::string& source) {
  ServerMessage m;
  if (size > std::size_t(INT32_MAX) || !m.ParseFromArray(data, int(size)) ||
      m.body_case() == ServerMessage::BODY_NOT_SET)
    throw WireError(ERROR_MALFORMED, source, "not a cslam ServerMessage (" + std::to_string(size) + " bytes)");
  return m;
}

const char* body_name(const ClientMessage& message) {
  switch (message.body_case()) {
    case ClientMessage::kHello:
      return "hello";
    case ClientMessage::kFrame:
      return "frame";
    case ClientMessage::kGoodbye:
      return "goodbye";
    case ClientMessage::kHeartbeat:
      return "heartbeat";
    default:
      return "empty";
  }
}

}  // namespace cslam::wire
