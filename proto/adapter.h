#pragma once
// The one place that knows both the wire schema (cslam.proto) and the SLAM library's types.
// Server and client both convert through here; src/ never sees protobuf.
#include <string>

#include "cslam.pb.h"
#include "codec/image_codec.h"
#include "core/error.h"
#include "system/rgbd_frame.h"

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

// The cheap checks of from_wire_frame (both images present, known encodings, sizes equal to the
// camera, finite timestamp), without decoding. Throws WireError like from_wire_frame.
void check_frame(const RgbdFrame& frame, const PinholeCamera& camera, const std::string& source);

// Checks encodings and sizes against the client's camera, then decodes both images. Decoders
// are bounded: each produces exactly width x height pixels or fails (a compressed stream that
// wants more output is corrupt), so work and memory per frame are bounded by the camera size.
// Throws WireError: ERROR_UNKNOWN_ENCODING, ERROR_SIZE_MISMATCH or ERROR_CORRUPT_IMAGE.
cslam::RgbdFrame from_wire_frame(const RgbdFrame& frame, const PinholeCamera& camera, const std::string& source);

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
