#pragma once
// The wire schema (cslam.proto, common.proto) and what both ends of the connection do with it:
// the protocol version, wire errors, a hello from a client's info, a frame's images encoded
// into a message, and parsing a message. The robot library (cslam_client_lib) needs only this:
// no SLAM library, no camera model beyond its fields. The server's side of the conversion
// (decoding and checking what a client sent) is proto/adapter.h.
#include <cstdint>
#include <string>

#include "cslam.pb.h"
#include "codec/image_codec.h"
#include "codec/byte_budget.h"
#include "codec/image_encoder.h"
#include "core/error.h"
#include "frame/rgbd_frame.h"

namespace cslam::wire {

constexpr ProtocolVersion kProtocolVersion = PROTOCOL_VERSION_2;
// The one-line explanation an old (or newer) peer gets with ERROR_BAD_VERSION.
std::string version_mismatch_text(int peer_version);

// A bad packet: one-line message naming its source, plus the code the server replies with.
class WireError : public InputError {
 public:
  WireError(ErrorCode code, const std::string& source, const std::string& message)
      : InputError(source, message), code_(code) {}
  ErrorCode code() const { return code_; }

 private:
  ErrorCode code_;
};

Encoding to_wire(RgbCodec codec);
Encoding to_wire(DepthCodec codec);

// Largest camera (width x height) a hello may announce unless the server says otherwise
// (cslam-server --max-pixels): bounds the memory one frame can decode to.
constexpr std::uint64_t kDefaultMaxPixels = 1920ull * 1080ull;

// ClientInfo -> Hello (the server's from_hello, proto/adapter.h, is the way back).
Hello to_hello(const ClientInfo& info);

// Encodes a full frame's images with the stream's encoder into `out` (reused to avoid
// reallocations). With an enabled budget the colour is the finest its allowance takes
// (ImageEncoder::rgb_within, codec/byte_budget.h); the caller adds the sent message to it.
// Returns whether the budget made the colour finer than the stream's codec.
bool to_wire_frame(const cslam::RgbdFrame& frame, ImageEncoder& images, RgbdFrame* out,
                   const ByteBudget* budget = nullptr);
// A light frame: `colour_packet` is the next packet of the robot's colour stream
// (video::H264Encoder), sent as RGB_H264; with depth_subsample >= 2 the frame's depth goes
// along at every S-th pixel of every S-th row (options.depth, lossless), else no depth.
void to_wire_light_frame(const cslam::RgbdFrame& frame, const Bytes& colour_packet, int depth_subsample,
                         const CodecOptions& options, RgbdFrame* out);

// Parses one ZeroMQ message body; throws WireError(ERROR_MALFORMED) on bytes that are not a
// ClientMessage with a body.
ClientMessage parse_client_message(const void* data, std::size_t size, const std::string& source);
// Parses a server reply; throws WireError(ERROR_MALFORMED).
ServerMessage parse_server_message(const void* data, std::size_t size, const std::string& source);

const char* body_name(const ClientMessage& message);

}  // namespace cslam::wire
