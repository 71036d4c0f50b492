#pragma once
// The server's side of the wire: what a client sent, checked and turned into the SLAM library's
// types (a hello into a ClientInfo with a validated camera, a frame message into a decoded
// RgbdFrame). Together with proto/wire.h (both ends) and proto/pose_feedback.h (acks) it is the
// one place that knows both the wire schema and the SLAM types; src/ never sees protobuf.
#include <cstdint>
#include <string>

#include "proto/wire.h"

namespace cslam::video {
class H264Decoder;
}

namespace cslam::wire {

// Hello -> ClientInfo. Throws WireError (ERROR_BAD_VERSION / ERROR_BAD_HELLO, also for a camera
// of more than max_pixels pixels).
ClientInfo from_hello(const Hello& hello, const std::string& source, std::uint64_t max_pixels = kDefaultMaxPixels);

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

}  // namespace cslam::wire
