#pragma once
// The one place that knows both the wire schema (cslam.proto) and the SLAM library's types.
// Server and client both convert through here; src/ never sees protobuf.
#include <string>

#include "cslam.pb.h"
#include "codec/image_codec.h"
#include "core/error.h"
#include "frame/rgbd_frame.h"

namespace cslam::video {
class H264Decoder;
}

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

// Hello <-> ClientInfo. from_hello throws WireError (ERROR_BAD_VERSION / ERROR_BAD_HELLO, also
// for a camera of more than max_pixels pixels).
Hello to_hello(const ClientInfo& info);
ClientInfo from_hello(const Hello& hello, const std::string& source, std::uint64_t max_pixels = kDefaultMaxPixels);

// Encodes a frame's images with the given codecs into `out` (reused to avoid reallocations).
void to_wire_frame(const cslam::RgbdFrame& frame, const CodecOptions& options, RgbdFrame* out);
// A light frame: `colour_packet` is the next packet of the robot's colour stream
// (video::H264Encoder), sent as RGB_H264; with depth_subsample >= 2 the frame's depth goes
// along at every S-th pixel of every S-th row (options.depth, lossless), else no depth.
void to_wire_light_frame(const cslam::RgbdFrame& frame, const Bytes& colour_packet, int depth_subsample,
                         const CodecOptions& options, RgbdFrame* out);
// Whether a frame (accepted by check_frame) may become a keyframe: full depth and colour that
// decodes on its own. Only such frames are kept for the dense map.
bool keyframe_eligible(const RgbdFrame& frame);

// The cheap checks of from_wire_frame (colour present; known encodings; sizes equal to the
// camera's, or its subsampled size for subsampled depth; full depth only with colour that decodes
// on its own; finite timestamp), without decoding. Throws WireError like from_wire_frame.
void check_frame(const RgbdFrame& frame, const PinholeCamera& camera, const std::string& source);

// Checks encodings and sizes against the client's camera, then decodes both images. Decoders
// are bounded: each produces exactly width x height pixels or fails (a compressed stream that
// wants more output is corrupt), so work and memory per frame are bounded by the camera size.
// RGB_H264 colour is decoded by the client's `colour_stream` (null: refused). A light frame comes
// back with an empty depth image, or subsampled depth spread to full size (depth_subsample > 1).
// Throws WireError: ERROR_UNKNOWN_ENCODING, ERROR_SIZE_MISMATCH, ERROR_CORRUPT_IMAGE, or
// ERROR_STREAM_GAP (the stream lacks this packet's reference).
cslam::RgbdFrame from_wire_frame(const RgbdFrame& frame, const PinholeCamera& camera, const std::string& source,
                                 video::H264Decoder* colour_stream = nullptr);

// Moves a frame's image bytes out of the message (after from_wire_frame accepted it) into the
// form the keyframe store keeps: the received payload, never re-encoded.
EncodedRgbd take_encoded(RgbdFrame& frame);

// Parses one ZeroMQ message body; throws WireError(ERROR_MALFORMED) on bytes that are not a
// ClientMessage with a body.
ClientMessage parse_client_message(const void* data, std::size_t size, const std::string& source);
// Parses a server reply; throws WireError(ERROR_MALFORMED).
ServerMessage parse_server_message(const void* data, std::size_t size, const std::string& source);

const char* body_name(const ClientMessage& message);

}  // namespace cslam::wire
