// FrameSender's live mode (declared in client/frame_sender.h): frames offered on the camera's
// clock, the newest kept while no credit is free, and the adaptive rate fed from what it drops.
#include "client/frame_sender.h"
#include "client/frame_sender_util.h"

namespace cslam::client {

using detail::log;
using detail::to_ms;

void FrameSender::offer_frame(const RgbdFrame& frame, Clock::time_point captured) {
  if (!colour_encoder_) {
    offer_encoded(encode(frame), captured);
    return;
  }
  if (!socket_) throw std::logic_error("FrameSender: offer before connect()");
  ++stats_.frames_offered;
  while (handle_reply(std::chrono::milliseconds(0))) {
  }
  if (has_waiting_frame()) dropped_live();
  waiting_.reset();
  RgbdFrame kept = frame;  // the caller may reuse its buffers before the frame leaves
  kept.bgr = frame.bgr.clone();
  kept.depth = frame.depth.clone();
  kept.live = true;
  waiting_raw_ = std::move(kept);
  waiting_captured_ = captured;
  send_waiting_if_credit();
}

void FrameSender::offer_encoded(wire::RgbdFrame frame, Clock::time_point captured) {
  if (!socket_) throw std::logic_error("FrameSender: offer before connect()");
  ++stats_.frames_offered;
  while (handle_reply(std::chrono::milliseconds(0))) {
  }
  if (has_waiting_frame()) dropped_live();  // a newer frame makes the waiting one stale
  waiting_raw_.reset();
  frame.set_live(true);
  waiting_ = std::move(frame);
  waiting_captured_ = captured;
  send_waiting_if_credit();
}

void FrameSender::dropped_live() {
  ++stats_.frames_dropped_live;
  rate_.on_live_drop(Clock::now());
  note_rate();
}

void FrameSender::note_rate() {
  if (rate_.depth_every() != stats_.depth_every)
    log()->debug("client {}: link {} (base latency {:.0f} ms): depth every {} frames", config_.info.id,
                 rate_.depth_every() > stats_.depth_every ? "queues" : "calm", rate_.base_ms(), rate_.depth_every());
  stats_.depth_every = rate_.depth_every();
  stats_.rate_steps_down = rate_.steps_down();
  stats_.rate_steps_up = rate_.steps_up();
}

void FrameSender::send_waiting_if_credit() {
  if (credits_ == 0) return;
  if (waiting_raw_) {
    wire::RgbdFrame encoded = encode_next(*waiting_raw_);
    encoded.set_live(true);
    waiting_raw_.reset();
    send_now(encoded, waiting_captured_);
    return;
  }
  if (!waiting_) return;
  send_now(*waiting_, waiting_captured_);
  waiting_.reset();
}

void FrameSender::service_until(Clock::time_point until) {
  if (!socket_) throw std::logic_error("FrameSender: service before connect()");
  for (;;) {
    send_waiting_if_credit();
    const auto now = Clock::now();
    if ((in_flight_ > 0 || has_waiting_frame()) && now - last_reply_ > to_ms(config_.reply_timeout_s)) {
      reconnect();
      continue;
    }
    if (credits_ == 0) send_heartbeat_if_due();
    if (now >= until) return;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - now) + std::chrono::milliseconds(1);
    handle_reply(std::min(left, to_ms(config_.heartbeat_interval_s)));
  }
}

}  // namespace cslam::client
