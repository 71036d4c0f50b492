#include "client/frame_sender.h"
#include "client/frame_sender_util.h"

#include <algorithm>

#include "codec/depth_subsample.h"
#include "core/log.h"

namespace cslam::client {

using detail::log;
using detail::to_ms;

FrameSender::FrameSender(SenderConfig config)
    : config_(std::move(config)),
      context_(1),
      full_images_(config_.codecs, cv::Size(config_.info.camera.width, config_.info.camera.height)),
      rate_(config_.adapt, std::max(config_.depth_every, 1)),
      budget_(config_.budget) {
  config_.info.camera.validate();  // the camera model alone (cslam_camera): no calib3d
  if (config_.depth_every < 1) throw ConfigError("SenderConfig::depth_every must be >= 1");
  if (config_.light_depth_subsample < 0 || config_.light_depth_subsample == 1 ||
      config_.light_depth_subsample > kMaxDepthSubsample)
    throw ConfigError("SenderConfig::light_depth_subsample must be 0 (no depth) or 2.." +
                      std::to_string(kMaxDepthSubsample));
  stats_.depth_every = config_.depth_every;
  if (config_.colour_stream_on()) {
    config_.colour_stream.validate();
    colour_encoder_ = std::make_unique<video::H264Encoder>(config_.info.camera.width, config_.info.camera.height,
                                                           config_.colour_stream);
  }
}

FrameSender::~FrameSender() = default;

void FrameSender::open_socket() {
  socket_ = std::make_unique<zmq::socket_t>(context_, zmq::socket_type::dealer);
  socket_->set(zmq::sockopt::linger, 2000);  // let a goodbye leave before close
  socket_->set(zmq::sockopt::sndtimeo, int(config_.reply_timeout_s * 1000));
  if (!config_.server_public_key.empty()) {
    socket_->set(zmq::sockopt::curve_serverkey, config_.server_public_key);
    socket_->set(zmq::sockopt::curve_publickey, config_.public_key);
    socket_->set(zmq::sockopt::curve_secretkey, config_.secret_key);
  }
  socket_->connect(config_.server);
}

void FrameSender::connect() {
  open_socket();
  welcomed_ = false;
  key_wanted_ = true;  // a restarted server has no colour stream of ours; frames in flight may be lost
  wire::ClientMessage hello;
  *hello.mutable_hello() = wire::to_hello(config_.info);
  hello.mutable_hello()->set_new_session(config_.new_session && !session_started_);
  send_message(hello);
  const auto deadline = Clock::now() + to_ms(config_.reply_timeout_s);
  while (!welcomed_) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    if (left.count() <= 0)
      throw ConnectionError("client " + std::to_string(config_.info.id) + ": no welcome from " + config_.server +
                            " within " + std::to_string(config_.reply_timeout_s) + " s");
    handle_reply(left);
    if (hello_busy_ && !welcomed_) {  // our previous connection has not timed out yet: ask again shortly
      hello_busy_ = false;
      handle_reply(std::min(left, std::chrono::milliseconds(500)));
      send_message(hello);
    }
  }
}

void FrameSender::reconnect() {
  for (int attempt = 1;; ++attempt) {
    ++stats_.reconnects;
    log()->warn("client {}: reconnecting to {} (attempt {})", config_.info.id, config_.server, attempt);
    try {
      connect();
      return;
    } catch (const ConnectionError&) {
      if (attempt >= config_.max_reconnects) throw;
    }
  }
}

wire::RgbdFrame FrameSender::encode_full(const RgbdFrame& frame, bool spend) {
  wire::RgbdFrame out;
  // The budget spends room only while the link is calm: a rate controller that stepped down
  // (full frames less often) would otherwise see the bytes it saved spent again.
  const bool calm = !config_.adapt.enabled || rate_.level() == 0;
  if (wire::to_wire_frame(frame, full_images_, &out, calm && spend ? &budget_ : nullptr)) ++stats_.frames_finer;
  return out;
}

wire::RgbdFrame FrameSender::encode_next(const RgbdFrame& frame) {
  const bool with_depth = !colour_encoder_ || full_clock_.next(depth_wanted_, rate_.depth_every());
  if (with_depth) {
    const std::uint64_t seq = seq_ + 1;  // encode_next runs right before the frame is sent with the next seq
    const bool spend = keyframe_hint_.on_full_frame(seq, depth_wanted_);
    if (depth_request_seq_ > 0) {  // answers a request: how many frames after the asking one
      const std::uint64_t lag = seq_ + 1 - depth_request_seq_;
      stats_.depth_request_lag_sum += lag;
      stats_.depth_request_lag_max = std::max(stats_.depth_request_lag_max, lag);
      ++stats_.depth_requests_met;
    }
    depth_request_seq_ = 0;
    depth_wanted_ = false;
    last_full_seq_ = seq;
    return encode_full(frame, spend);
  }
  wire::RgbdFrame out;
  const bool key = key_wanted_;
  wire::to_wire_light_frame(frame, colour_encoder_->encode(frame.bgr, key), config_.light_depth_subsample,
                            config_.codecs, &out);
  key_wanted_ = false;
  ++stats_.frames_light;
  if (key) {
    ++stats_.colour_key_packets;
    last_key_seq_ = seq_ + 1;  // encode_next runs right before the frame is sent with the next seq
  }
  return out;
}

std::size_t FrameSender::send_frame(const RgbdFrame& frame) {
  // Credits first: a lean stream's frame is encoded only once it can leave.
  for (;;) {
    send_resends(true);
    wait_for_credit();
    if (resend_.empty()) break;
  }
  wire::RgbdFrame encoded = encode_next(frame);
  return send_encoded(encoded);
}

std::size_t FrameSender::send_encoded(wire::RgbdFrame& frame) {
  if (!socket_) throw std::logic_error("FrameSender: send before connect()");
  const auto captured = Clock::now();
  // Frames the server lacks go first (a reconnect while waiting for a credit may queue some).
  for (;;) {
    send_resends(true);
    wait_for_credit();
    if (resend_.empty()) break;
  }
  frame.set_live(false);
  return send_now(frame, captured);
}

std::size_t FrameSender::send_now(wire::RgbdFrame& frame, Clock::time_point captured) {
  frame.set_client_id(config_.info.id);
  frame.set_seq(++seq_);
  wire::ClientMessage message;
  message.mutable_frame()->Swap(&frame);
  const std::string body = message.SerializeAsString();
  message.mutable_frame()->Swap(&frame);  // hand the caller's buffers back
  send_body(body);
  ++stats_.frames_sent;
  stats_.bytes_sent += body.size();
  budget_.add(body.size());
  if (frame.rgb().encoding() == wire::RGB_H264) stats_.bytes_light += body.size();
  captured_at_[seq_] = captured;
  if (!frame.live() && config_.resend_buffer_bytes > 0) {
    kept_bytes_ += body.size();
    kept_.emplace_back(seq_, body);
    while (kept_bytes_ > config_.resend_buffer_bytes && !kept_.empty()) {
      kept_bytes_ -= kept_.front().second.size();
      kept_.pop_front();
    }
  }
  return body.size();
}

void FrameSender::send_body(const std::string& body) {
  if (!socket_->send(zmq::buffer(body), zmq::send_flags::none))
    throw ConnectionError("client " + std::to_string(config_.info.id) + ": send timed out");
  --credits_;
  ++in_flight_;
}

void FrameSender::plan_resend(std::uint64_t server_last_seq) {
  resend_.clear();
  if (server_last_seq >= seq_) return;
  for (const auto& [seq, body] : kept_)
    if (seq > server_last_seq) resend_.emplace_back(seq, body);
  const std::uint64_t missing = seq_ - server_last_seq;
  const std::uint64_t lost = missing - resend_.size();
  if (lost > 0) {
    stats_.frames_lost += lost;
    log()->warn(
        "client {}: the server lacks frames {}..{}; {} of them are no longer kept (live, or beyond the {} MB "
        "re-send buffer) and are lost",
        config_.info.id, server_last_seq + 1, seq_, lost, config_.resend_buffer_bytes >> 20);
  }
  if (!resend_.empty())
    log()->warn("client {}: the server lacks frames {}..{}: sending {} kept frame(s) again", config_.info.id,
                server_last_seq + 1, seq_, resend_.size());
}

void FrameSender::send_resends(bool wait) {
  while (!resend_.empty()) {
    if (credits_ == 0) {
      if (!wait) return;
      wait_for_credit();  // may reconnect, which plans the re-sends again
      continue;
    }
    const auto [seq, body] = resend_.front();
    resend_.pop_front();
    send_body(body);
    ++stats_.frames_resent;
    captured_at_.emplace(seq, Clock::now());
  }
}

void FrameSender::send_heartbeat_if_due() {
  const auto now = Clock::now();
  if (now - last_heartbeat_ < to_ms(config_.heartbeat_interval_s)) return;
  wire::ClientMessage hb;
  hb.mutable_heartbeat()->set_client_id(config_.info.id);
  send_message(hb);
  ++stats_.heartbeats;
  last_heartbeat_ = now;
}

void FrameSender::wait_for_credit() {
  // Replies that already arrived first, credit or not: their poses (and latency, and a lean
  // stream's depth requests) are then as fresh as the robot can have them, not read only once
  // the window is used up.
  while (handle_reply(std::chrono::milliseconds(0))) {
  }
  while (credits_ == 0) {
    if (Clock::now() - last_reply_ > to_ms(config_.reply_timeout_s)) {
      reconnect();
      continue;
    }
    send_heartbeat_if_due();
    handle_reply(to_ms(config_.heartbeat_interval_s));
  }
}

std::vector<wire::PoseFeedback> FrameSender::take_poses() {
  std::vector<wire::PoseFeedback> out(poses_.begin(), poses_.end());
  poses_.clear();
  return out;
}

void FrameSender::on_ack(const wire::Ack& ack) {
  wire::PoseFeedback f = wire::from_wire_ack(ack);
  const auto now = Clock::now();
  if (auto it = captured_at_.find(ack.seq()); it != captured_at_.end()) {
    f.latency_ms = std::chrono::duration<double, std::milli>(now - it->second).count();
    captured_at_.erase(captured_at_.begin(), std::next(it));  // older seqs cannot be acked any more
    rate_.on_ack(f.latency_ms, now);
    note_rate();
  }
  // A request about a frame sent before the last full frame is already met by it (the acks of
  // the frames in flight may all ask).
  if (f.want_depth && colour_encoder_ && ack.seq() > last_full_seq_) {
    if (!depth_wanted_) depth_request_seq_ = ack.seq();
    depth_wanted_ = true;
    ++stats_.depth_requests;
  }
  keyframe_hint_.on_ack(ack.seq(), f.keyframe_due_in);
  latest_pose_ = f;
  if (pose_callback_) {
    pose_callback_(f);
    return;
  }
  if (poses_.size() >= kMaxQueuedPoses) {
    poses_.pop_front();
    ++stats_.poses_dropped;
  }
  poses_.push_back(std::move(f));
}

void FrameSender::keep_alive(double timeout_s) {
  const auto deadline = Clock::now() + to_ms(timeout_s);
  while (Clock::now() < deadline) {
    const auto now = Clock::now();
    send_heartbeat_if_due();
    handle_reply(std::min(to_ms(config_.heartbeat_interval_s),
                          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - now)));
  }
}

bool FrameSender::goodbye(double timeout_s) {
  if (!socket_) return false;
  const auto deadline = Clock::now() + to_ms(timeout_s);
  while ((in_flight_ > 0 || has_waiting_frame() || !resend_.empty()) && Clock::now() < deadline) {
    send_resends(false);
    send_waiting_if_credit();  // live: the last frame still goes out when its credit comes
    handle_reply(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()));
  }
  const bool all_acked = in_flight_ == 0 && !has_waiting_frame() && resend_.empty();
  if (!all_acked) log()->warn("client {}: {} frame(s) not acknowledged before goodbye", config_.info.id, in_flight_);
  wire::ClientMessage bye;
  bye.mutable_goodbye()->set_client_id(config_.info.id);
  bye.mutable_goodbye()->set_frames_sent(stats_.frames_sent);
  send_message(bye);
  socket_.reset();  // linger delivers the goodbye
  return all_acked;
}

void FrameSender::send_message(const wire::ClientMessage& message) {
  const std::string body = message.SerializeAsString();
  if (!socket_->send(zmq::buffer(body), zmq::send_flags::none))
    throw ConnectionError("client " + std::to_string(config_.info.id) + ": send timed out");
}

bool FrameSender::handle_reply(std::chrono::milliseconds timeout) {
  zmq::pollitem_t item{socket_->handle(), 0, ZMQ_POLLIN, 0};
  zmq::poll(&item, 1, timeout);
  if (!(item.revents & ZMQ_POLLIN)) return false;
  zmq::message_t reply;
  if (!socket_->recv(reply, zmq::recv_flags::dontwait)) return false;
  last_reply_ = Clock::now();
  const std::string source = "reply from " + config_.server;
  const wire::ServerMessage m = wire::parse_server_message(reply.data(), reply.size(), source);
  switch (m.body_case()) {
    case wire::ServerMessage::kWelcome: {
      const wire::Welcome& w = m.welcome();
      window_ = w.window();
      credits_ = w.credits();
      in_flight_ = w.window() >= w.credits() ? w.window() - w.credits() : 0;
      if (w.resumed()) plan_resend(w.last_seq());
      seq_ = std::max(seq_, w.last_seq());
      if (w.version() != wire::kProtocolVersion)
        throw ConnectionError("client " + std::to_string(config_.info.id) + ": server " + config_.server +
                              " speaks protocol version " + std::to_string(int(w.version())) + ", this client " +
                              std::to_string(int(wire::kProtocolVersion)) + ": update the server");
      welcomed_ = true;
      session_started_ = true;
      log()->info("client {}: {} session at {}, window {}, {} credits, last seq {}", config_.info.id,
                  w.resumed() ? "resumed" : "new", config_.server, w.window(), w.credits(), w.last_seq());
      break;
    }
    case wire::ServerMessage::kAck:
      credits_ += m.ack().credits();
      if (in_flight_ > 0) --in_flight_;
      ++stats_.acks;
      on_ack(m.ack());
      break;
    case wire::ServerMessage::kError: {
      const wire::Error& e = m.error();
      const std::string code = wire::ErrorCode_Name(e.code());
      ++stats_.errors[code];
      credits_ += e.credits();
      if (e.seq() != 0 && in_flight_ > 0) --in_flight_;
      // A frame that reached a server which no longer knows this session is not refused: the
      // reconnect below resumes, and the frame goes again if the server lacks it.
      const bool unregistered = e.code() == wire::ERROR_NOT_REGISTERED && welcomed_;
      if (e.seq() != 0 && !unregistered) ++stats_.frames_refused;
      if (e.seq() != 0) captured_at_.erase(e.seq());
      log()->warn("client {}: server error {} for seq {}: {}", config_.info.id, code, e.seq(), e.message());
      if (e.code() == wire::ERROR_SESSION_BUSY && !welcomed_) hello_busy_ = true;
      if (e.code() == wire::ERROR_STREAM_GAP) {  // the server's colour stream lost its reference
        ++stats_.stream_gaps;
        if (e.seq() > last_key_seq_) key_wanted_ = true;  // else a key packet sent since heals it
      }
      if (e.code() == wire::ERROR_BAD_VERSION || e.code() == wire::ERROR_BAD_HELLO ||
          e.code() == wire::ERROR_SHUTTING_DOWN || e.code() == wire::ERROR_TOO_MANY_CLIENTS ||
          (e.code() == wire::ERROR_NOT_AUTHORIZED && e.seq() == 0))
        throw ConnectionError("client " + std::to_string(config_.info.id) + ": server refused: " + e.message());
      if (e.code() == wire::ERROR_NOT_REGISTERED && welcomed_) reconnect();
      break;
    }
    case wire::ServerMessage::kHeartbeatAck:
      break;
    default:
      break;
  }
  return true;
}

}  // namespace cslam::client
