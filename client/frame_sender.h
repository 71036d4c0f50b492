#pragma once
// Client library: what a robot program links to stream its RGB-D frames to cslam-server.
//   FrameSender sender(config);   // config.info: client id, name, camera
//   sender.connect();             // hello -> welcome (credits)
//   sender.send_frame(frame);     // lossless: encodes, waits for a credit, sends
//   sender.offer_frame(frame);    // live: sends if a credit is free, else keeps only the newest
//   sender.service_until(t);      // live: between captures, handles acks, sends the kept frame
//   sender.goodbye();             // waits for the last acks, says goodbye
// Flow control: at most `window` frames are unacknowledged. Lossless mode (send_frame) blocks
// (sending heartbeats) until the server hands a credit back. Live mode never waits for a credit:
// a frame offered with none free replaces the one kept waiting (the older is dropped, counted),
// and the server may skip a live frame that a newer one overtook in its queue.
// Pose feedback: every ack carries the frame's tracking state and, when tracked, its pose in the
// client's group frame; read them with take_poses() or get them through set_pose_callback().
// A silent server triggers a reconnect that resumes the session (same client id, sequence
// numbers continue). One thread uses a FrameSender (it owns a ZeroMQ socket).
#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <memory>
#include <string>

#include <zmq.hpp>

#include "codec/byte_budget.h"
#include "codec/keyframe_hint.h"
#include "codec/image_codec.h"
#include "client/rate_control.h"
#include "codec/video_codec.h"
#include "proto/wire.h"
#include "proto/pose_feedback.h"
#include "frame/full_frame_clock.h"
#include "frame/rgbd_frame.h"

namespace cslam::client {

struct SenderConfig {
  std::string server = "tcp://127.0.0.1:5555";
  ClientInfo info;
  CodecOptions codecs;
  double reply_timeout_s = 10.0;      // no reply for this long while waiting -> reconnect
  double heartbeat_interval_s = 1.0;  // heartbeats while waiting for credits
  int max_reconnects = 3;             // consecutive failed attempts before giving up
  // CURVE (docs/security.md): the server's public key and this robot's key pair, Z85. Empty
  // server_public_key: plain TCP (only against a loopback server or one run with --insecure-bind).
  std::string server_public_key, public_key, secret_key;
  bool new_session = false;  // first hello asks for a new recording session (new map)
  // Lossless frames already sent are kept (newest first, up to this many bytes of wire messages)
  // so that a server which restarted from an older snapshot, or lost frames in flight, gets
  // them again: a resumed Welcome's last_seq says where the server stands. 0: keep none.
  std::size_t resend_buffer_bytes = std::size_t(128) << 20;
  // Lean stream (docs/network.md): the next frame after an ack asks for it (want_depth: a
  // keyframe is due), and otherwise the depth_every-th frame after the last full one, is a full
  // frame (frame/full_frame_clock.h): full depth with standalone colour (`codecs`). The frames
  // between are light: colour as packets of one H.264 stream, and depth at every
  // light_depth_subsample-th pixel of every such row (0: no depth). Keyframes come from full
  // frames alone, so the map and the dense model see full-quality images. depth_every 1: every
  // frame is full (no colour stream).
  int depth_every = 1;
  int light_depth_subsample = 4;
  video::H264Options colour_stream = video::light_colour_stream();
  // Adaptive rate (client/rate_control.h): depth_every becomes the finest step of a ladder the
  // sender moves along as the acks' latency says the link queues or is calm.
  RateControlConfig adapt;
  // Byte budget (codec/byte_budget.h): the full frames' colour is the finest JPEG quality that
  // keeps the stream within budget.bytes_per_s, else `codecs`' own; 0: always `codecs`' own.
  // Set budget.frame_rate to the stream's nominal rate. With `adapt`, only while the rate
  // controller is at its finest step (the link calm). In a lean stream, only on the full frames
  // the server's acks expect to become keyframes (codec/keyframe_hint.h).
  ByteBudgetConfig budget;
  // Whether frames may be light (a colour stream exists): a lean stream or an adaptive one.
  bool colour_stream_on() const { return depth_every > 1 || adapt.enabled; }
};

struct SenderStats {
  std::uint64_t frames_sent = 0, bytes_sent = 0, acks = 0, heartbeats = 0, reconnects = 0;
  std::uint64_t frames_offered = 0;             // live: frames given to offer_*()
  std::uint64_t frames_dropped_live = 0;        // live: replaced by a newer frame before a credit came
  std::uint64_t poses_dropped = 0;              // feedback not taken before the poll queue was full
  std::map<std::string, std::uint64_t> errors;  // server error code name -> count
  std::uint64_t frames_refused = 0;             // errors about a sent frame (seq != 0): frames not delivered
  std::uint64_t frames_resent = 0;              // sent again after a resumed session said the server lacked them
  std::uint64_t frames_lost = 0;                // the server lacked them and they were no longer kept (or live)
  // Lean stream: light frames sent, key packets of the colour stream, acks asking for full
  // depth, and stream gaps the server reported (each answered with a key packet).
  std::uint64_t frames_light = 0, colour_key_packets = 0, depth_requests = 0, stream_gaps = 0;
  // Requests answered by a full frame, and frames from the asking frame to that answer (1: the
  // next frame; it bounds how late a keyframe the server deferred comes).
  std::uint64_t depth_requests_met = 0, depth_request_lag_sum = 0, depth_request_lag_max = 0;
  std::uint64_t bytes_light = 0;  // wire bytes of the light frames
  // Adaptive rate: steps down (full frames less often) and back up; the current depth_every.
  std::uint64_t rate_steps_down = 0, rate_steps_up = 0;
  int depth_every = 1;
  // Byte budget: full frames whose colour the budget made finer than the stream's codec.
  std::uint64_t frames_finer = 0;
};

// The server refused us or stopped answering.
class ConnectionError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class FrameSender {
 public:
  explicit FrameSender(SenderConfig config);
  ~FrameSender();
  FrameSender(const FrameSender&) = delete;
  FrameSender& operator=(const FrameSender&) = delete;

  // Sends the hello and waits for the welcome. Throws ConnectionError on refusal or timeout.
  void connect();
  // Drops the socket and connects again with the same client id (session resumed).
  void reconnect();

  // Encodes the frame's images with config.codecs (the frame's client/seq are ignored: the
  // sender stamps its own id and the next sequence number). Always with depth. With
  // --rgb-codec h264-intra the pictures come from one encoder: encode frames in sending order.
  wire::RgbdFrame encode(const RgbdFrame& frame) { return encode_full(frame, true); }
  // The next frame of the stream: with depth (encode()) or, in a lean stream, colour only as the
  // colour stream's next packet. Call it only for a frame that is sent right away.
  wire::RgbdFrame encode_next(const RgbdFrame& frame);
  // Waits for a credit, stamps id + seq, sends. Returns the message size in bytes.
  std::size_t send_encoded(wire::RgbdFrame& frame);
  std::size_t send_frame(const RgbdFrame& frame);

  // Live mode: never waits for a credit. Handles pending replies, then sends the frame (marked
  // live) if a credit is free; otherwise keeps it as the one waiting frame, dropping (and
  // counting) the frame that waited before. `captured` is when the camera took it (pose latency
  // is measured from there).
  void offer_encoded(wire::RgbdFrame frame, std::chrono::steady_clock::time_point captured);
  void offer_frame(const RgbdFrame& frame,
                   std::chrono::steady_clock::time_point captured = std::chrono::steady_clock::now());
  // Live mode, between captures: handles replies until `until`, sending the waiting frame as
  // soon as a credit comes back (heartbeats and reconnects as in lossless mode).
  void service_until(std::chrono::steady_clock::time_point until);
  bool has_waiting_frame() const { return waiting_.has_value() || waiting_raw_.has_value(); }

  // Pose feedback. With a callback set, every ack's feedback goes there (on the calling thread,
  // from inside the sender's calls); otherwise it is queued (bounded) for take_poses().
  void set_pose_callback(std::function<void(const wire::PoseFeedback&)> callback) {
    pose_callback_ = std::move(callback);
  }
  std::vector<wire::PoseFeedback> take_poses();
  // The newest feedback received so far (tracked or not).
  const std::optional<wire::PoseFeedback>& latest_pose() const { return latest_pose_; }

  // Handles replies for up to timeout_s (heartbeats if due), for robots that are idle a while.
  void keep_alive(double timeout_s);
  // Waits (up to timeout_s) until every sent frame is acknowledged, then says goodbye.
  // Returns false if some acks did not arrive in time (goodbye is sent anyway).
  bool goodbye(double timeout_s = 30.0);

  std::uint32_t credits() const { return credits_; }
  std::uint32_t in_flight() const { return in_flight_; }
  std::uint32_t window() const { return window_; }
  std::uint64_t last_seq() const { return seq_; }
  const SenderStats& stats() const { return stats_; }

 private:
  using Clock = std::chrono::steady_clock;
  void open_socket();
  void send_message(const wire::ClientMessage& message);
  // Receives and handles one reply if any arrives within timeout; returns true if one did.
  bool handle_reply(std::chrono::milliseconds timeout);
  void wait_for_credit();
  void send_heartbeat_if_due();
  void send_waiting_if_credit();
  // After a resumed welcome: queue the kept frames the server lacks (seq > its last_seq).
  void plan_resend(std::uint64_t server_last_seq);
  // Sends queued re-sends while credits last; with `wait`, waits for credits until none is left.
  void send_resends(bool wait);
  void send_body(const std::string& body);
  std::size_t send_now(wire::RgbdFrame& frame, Clock::time_point captured);
  void on_ack(const wire::Ack& ack);
  void dropped_live();  // counts the waiting frame a newer one replaced; tells the rate controller
  void note_rate();     // the rate controller's state into stats_

  static constexpr std::size_t kMaxQueuedPoses = 100000;

  SenderConfig config_;
  zmq::context_t context_;
  std::unique_ptr<zmq::socket_t> socket_;
  std::uint32_t credits_ = 0, in_flight_ = 0, window_ = 0;
  std::uint64_t seq_ = 0;
  bool session_started_ = false;  // a welcome was received (reconnects resume, never restart)
  bool welcomed_ = false;
  bool hello_busy_ = false;  // the server asked to retry the hello (its old connection is still live)
  Clock::time_point last_reply_, last_heartbeat_;
  SenderStats stats_;
  std::optional<wire::RgbdFrame> waiting_;  // live: the newest frame without a credit
  // Live, lean stream: the waiting frame is encoded only when it is sent (a colour packet that
  // never leaves would break the stream).
  std::optional<RgbdFrame> waiting_raw_;
  ImageEncoder full_images_;  // full frames' images (config.codecs)
  std::unique_ptr<video::H264Encoder> colour_encoder_;
  RateController rate_;
  ByteBudget budget_;  // config.budget; every sent frame's message is added
  FullFrameClock full_clock_;
  KeyframeHint keyframe_hint_;           // lean stream: which full frames the budget is for
  bool depth_wanted_ = true;             // the first frame carries depth
  bool key_wanted_ = true;               // the first colour packet, and the first after a gap or reconnect, is a key
  std::uint64_t last_key_seq_ = 0;       // seq of the last key packet sent (a gap before it is healed)
  std::uint64_t depth_request_seq_ = 0;  // the frame whose ack asked for the pending full depth (0: none)
  std::uint64_t last_full_seq_ = 0;      // seq of the last full frame sent (a request before it is met)
  Clock::time_point waiting_captured_;
  std::map<std::uint64_t, Clock::time_point> captured_at_;  // seq -> capture time, until acked
  std::function<void(const wire::PoseFeedback&)> pose_callback_;
  std::deque<wire::PoseFeedback> poses_;
  std::deque<std::pair<std::uint64_t, std::string>> kept_;  // seq -> wire message, lossless frames
  std::size_t kept_bytes_ = 0;
  std::deque<std::pair<std::uint64_t, std::string>> resend_;  // queued by plan_resend, oldest first
  std::optional<wire::PoseFeedback> latest_pose_;

  // encode() with the budget (if any, and the link calm) only when `spend`.
  wire::RgbdFrame encode_full(const RgbdFrame& frame, bool spend);
};

}  // namespace cslam::client
