#include "server/receiver.h"

#include <cerrno>
#include <cstring>

#include "core/log.h"
#include "proto/pose_feedback.h"

namespace cslam::server {

namespace {

auto log() { return logger("server"); }

// Logs the first few occurrences of a repeated problem, then every 1000th.
bool should_log(std::uint64_t count) { return count <= 20 || count % 1000 == 0; }

std::string source_of(const Session* session, const std::string& routing_id) {
  if (session) return "client " + std::to_string(session->info.id);
  return "unregistered peer " + routing_id_text(routing_id);
}

std::string error_reason(wire::ErrorCode code) {
  std::string name = wire::ErrorCode_Name(code);
  if (name.rfind("ERROR_", 0) == 0) name = name.substr(6);
  for (char& c : name) c = char(std::tolower(static_cast<unsigned char>(c)));
  return name.empty() ? "unknown" : name;
}

}  // namespace

Receiver::Receiver(zmq::context_t& context, const ReceiverConfig& config, CollaborativeSystem& system,
                   DoneChannel& done, WakePipe& stop)
    : config_(config), system_(system), done_(done), stop_(stop), router_(context, zmq::socket_type::router),
      monitor_(context, zmq::socket_type::pair) {
  router_.set(zmq::sockopt::maxmsgsize, config_.max_message_bytes);
  router_.set(zmq::sockopt::router_handover, 1);
  router_.set(zmq::sockopt::linger, 0);
  const std::string monitor_endpoint = "inproc://cslam-router-monitor-" + std::to_string(reinterpret_cast<std::uintptr_t>(this));
  if (zmq_socket_monitor(router_.handle(), monitor_endpoint.c_str(), ZMQ_EVENT_ACCEPTED | ZMQ_EVENT_DISCONNECTED) != 0)
    throw zmq::error_t();
  monitor_.connect(monitor_endpoint);
  router_.bind(config_.bind);
  endpoint_ = router_.get(zmq::sockopt::last_endpoint);
  start_ = last_log_ = Clock::now();
  log()->info("listening on {} (window {} frames, max message {} bytes, heartbeat timeout {} s)", endpoint_,
              config_.window, config_.max_message_bytes, config_.heartbeat_timeout_s);
}

bool Receiver::run() {
  const auto tick = std::chrono::milliseconds(
      std::max<long>(20, long(std::min(config_.heartbeat_timeout_s / 4, config_.log_interval_s) * 1000)));
  for (;;) {
    zmq::pollitem_t items[] = {{router_.handle(), 0, ZMQ_POLLIN, 0},
                               {monitor_.handle(), 0, ZMQ_POLLIN, 0},
                               {nullptr, done_.read_fd(), ZMQ_POLLIN, 0},
                               {nullptr, stop_.read_fd(), ZMQ_POLLIN, 0}};
    try {
      zmq::poll(items, 4, tick);
    } catch (const zmq::error_t& e) {
      if (e.num() != EINTR) throw;
      continue;  // a signal: its handler has written to the stop pipe, seen on the next poll
    }
    if (items[3].revents & ZMQ_POLLIN) {
      log()->info("stop requested");
      return false;
    }
    if (items[2].revents & ZMQ_POLLIN) on_frames_done();
    if (items[0].revents & ZMQ_POLLIN) receive_pending();
    if (items[1].revents & ZMQ_POLLIN) on_monitor_event();
    check_timeouts();
    if (std::chrono::duration<double>(Clock::now() - last_log_).count() >= config_.log_interval_s) log_progress();
    if (config_.exit_when_done && sessions_.all_finished(config_.expected_clients)) {
      log()->info("all {} client(s) finished", sessions_.size());
      return true;
    }
  }
}

void Receiver::receive_pending() {
  // Bounded batch so credits and the stop pipe are serviced even under a flood.
  for (int n = 0; n < 64; ++n) {
    zmq::message_t identity;
    if (!router_.recv(identity, zmq::recv_flags::dontwait)) return;
    const Stopwatch timer;
    std::string routing_id(static_cast<const char*>(identity.data()), identity.size());
    std::vector<zmq::message_t> parts;
    while (true) {
      const bool more = parts.empty() ? identity.more() : parts.back().more();
      if (!more) break;
      parts.emplace_back();
      if (!router_.recv(parts.back(), zmq::recv_flags::none)) break;
    }
    Session* session = sessions_.by_routing_id(routing_id);
    if (parts.size() != 1) {
      drop(session, routing_id, "malformed", "message with " + std::to_string(parts.size()) + " parts");
      reply_error(routing_id, session ? session->info.id : 0, 0, wire::ERROR_MALFORMED,
                  "expected exactly one message part", 0);
      continue;
    }
    stats_.add_bytes(parts[0].size());
    if (session) {
      session->last_seen = Clock::now();
      ++stats_.client(session->info.id).messages;
    }
    wire::ClientMessage message;
    try {
      message = wire::parse_client_message(parts[0].data(), parts[0].size(), source_of(session, routing_id));
    } catch (const wire::WireError& e) {
      drop(session, routing_id, "malformed", e.what());
      reply_error(routing_id, session ? session->info.id : 0, 0, e.code(), e.what(), 0);
      continue;
    }
    switch (message.body_case()) {
      case wire::ClientMessage::kHello: on_hello(routing_id, message.hello()); break;
      case wire::ClientMessage::kFrame: on_frame(routing_id, message.frame(), parts[0].size(), timer); break;
      case wire::ClientMessage::kGoodbye: on_goodbye(routing_id, message.goodbye()); break;
      case wire::ClientMessage::kHeartbeat: on_heartbeat(routing_id, message.heartbeat()); break;
      default: break;
    }
  }
}

void Receiver::on_hello(const std::string& routing_id, const wire::Hello& hello) {
  const std::string source = "hello from peer " + routing_id_text(routing_id);
  ClientInfo info;
  try {
    info = wire::from_hello(hello, source);
    system_.add_client(info);  // keeps the map of a known client; throws if its camera changed
  } catch (const wire::WireError& e) {
    Session* known = hello.client_id() <= 0xffff ? sessions_.by_client(ClientId(hello.client_id())) : nullptr;
    drop(known, routing_id, error_reason(e.code()), e.what());
    reply_error(routing_id, ClientId(hello.client_id()), 0, e.code(), e.what(), 0);
    return;
  } catch (const std::exception& e) {  // std::invalid_argument: camera differs from the registered one
    drop(sessions_.by_client(info.id), routing_id, "bad_hello", source + ": " + e.what());
    reply_error(routing_id, info.id, 0, wire::ERROR_BAD_HELLO, e.what(), 0);
    return;
  }
  auto [session, resumed] = sessions_.open(info, routing_id, Clock::now());
  if (resumed) ++stats_.client(info.id).reconnects;
  ++stats_.client(info.id).messages;
  const std::uint32_t credits = session->in_flight >= config_.window ? 0 : config_.window - session->in_flight;
  log()->info("client {} ('{}') {} from peer {}, camera {}x{}, last seq {}, {} credits", info.id, info.name,
              resumed ? "reconnected" : "connected", routing_id_text(routing_id), info.camera.width,
              info.camera.height, session->last_seq, credits);
  wire::ServerMessage reply;
  wire::Welcome* w = reply.mutable_welcome();
  w->set_client_id(info.id);
  w->set_credits(credits);
  w->set_window(config_.window);
  w->set_last_seq(session->last_seq);
  w->set_resumed(resumed);
  w->set_max_message_bytes(std::uint64_t(config_.max_message_bytes));
  w->set_version(wire::kProtocolVersion);
  send(routing_id, reply);
}

void Receiver::on_frame(const std::string& routing_id, const wire::RgbdFrame& frame, std::size_t bytes,
                        const Stopwatch& timer) {
  Session* session = sessions_.by_routing_id(routing_id);
  const std::uint64_t seq = frame.seq();
  if (!session) {
    drop(nullptr, routing_id, "not_registered", "frame " + std::to_string(seq) + " before hello");
    reply_error(routing_id, ClientId(frame.client_id()), seq, wire::ERROR_NOT_REGISTERED, "send a hello first", 0);
    return;
  }
  const ClientId id = session->info.id;
  const std::string source = "client " + std::to_string(id) + " frame " + std::to_string(seq);
  ClientNetStats& net = stats_.client(id);
  net.bytes_received += bytes;
  if (session->state != SessionState::kActive) {
    log()->info("client {} is back (was {})", id, to_string(session->state));
    session->state = SessionState::kActive;
  }
  if (frame.client_id() != id) {
    drop(session, routing_id, "wrong_client", source + ": carries client id " + std::to_string(frame.client_id()));
    reply_error(routing_id, id, seq, wire::ERROR_WRONG_CLIENT, "client id differs from the hello", 1);
    return;
  }
  if (seq <= session->last_seq) {
    drop(session, routing_id, "duplicate_seq", source + ": not after the last accepted seq " + std::to_string(session->last_seq));
    reply_error(routing_id, id, seq, wire::ERROR_DUPLICATE_SEQ,
                "sequence number not above " + std::to_string(session->last_seq), 1);
    return;
  }
  if (session->in_flight >= config_.window) {
    drop(session, routing_id, "no_credit", source + ": more than " + std::to_string(config_.window) + " frames in flight");
    reply_error(routing_id, id, seq, wire::ERROR_NO_CREDIT, "no credit: wait for acks", 0);
    return;
  }
  cslam::RgbdFrame decoded;
  try {
    decoded = wire::from_wire_frame(frame, session->info.camera, source);
  } catch (const wire::WireError& e) {
    drop(session, routing_id, error_reason(e.code()), e.what());
    reply_error(routing_id, id, seq, e.code(), e.what(), 1);
    return;
  }
  bool accepted = false;
  try {
    accepted = system_.submit(std::move(decoded));
  } catch (const std::invalid_argument& e) {
    drop(session, routing_id, "rejected", source + ": " + e.what());
    reply_error(routing_id, id, seq, wire::ERROR_SIZE_MISMATCH, e.what(), 1);
    return;
  }
  if (!accepted) {
    drop(session, routing_id, "shutting_down", source + ": system is finishing");
    reply_error(routing_id, id, seq, wire::ERROR_SHUTTING_DOWN, "server is shutting down", 0);
    return;
  }
  ++session->in_flight;
  session->last_seq = seq;
  ++net.frames_accepted;
  if (net.decode_dispatch_ms.size() < kMaxTimingSamples) net.decode_dispatch_ms.push_back(timer.ms());
  stats_.note_frame(Clock::now());
}

void Receiver::on_goodbye(const std::string& routing_id, const wire::Goodbye& goodbye) {
  Session* session = sessions_.by_routing_id(routing_id);
  if (!session) {
    drop(nullptr, routing_id, "not_registered", "goodbye before hello");
    reply_error(routing_id, ClientId(goodbye.client_id()), 0, wire::ERROR_NOT_REGISTERED, "goodbye before hello", 0);
    return;
  }
  session->state = SessionState::kDone;
  ++stats_.client(session->info.id).goodbyes;
  log()->info("client {} said goodbye after {} frames sent, {} accepted, {} dropped", session->info.id,
              goodbye.frames_sent(), stats_.client(session->info.id).frames_accepted,
              stats_.client(session->info.id).dropped_total());
}

void Receiver::on_heartbeat(const std::string& routing_id, const wire::Heartbeat& heartbeat) {
  Session* session = sessions_.by_routing_id(routing_id);
  if (!session) {
    drop(nullptr, routing_id, "not_registered", "heartbeat before hello");
    reply_error(routing_id, ClientId(heartbeat.client_id()), 0, wire::ERROR_NOT_REGISTERED, "heartbeat before hello", 0);
    return;
  }
  ++stats_.client(session->info.id).heartbeats;
  if (session->state == SessionState::kDisconnected) {
    log()->info("client {} is back", session->info.id);
    session->state = SessionState::kActive;
  }
  wire::ServerMessage reply;
  reply.mutable_heartbeat_ack()->set_client_id(session->info.id);
  send(routing_id, reply);
}

void Receiver::on_frames_done() {
  for (const FrameDone& done : done_.drain()) {
    Session* session = sessions_.by_client(done.client);
    if (!session) continue;
    if (session->in_flight > 0) --session->in_flight;
    if (session->state != SessionState::kActive) continue;
    wire::ServerMessage reply;
    wire::to_wire_ack(done, 1, reply.mutable_ack());  // the frame's pose feedback and its credit
    send(session->routing_id, reply);
  }
}

void Receiver::on_monitor_event() {
  while (true) {
    zmq::message_t event, address;
    if (!monitor_.recv(event, zmq::recv_flags::dontwait)) return;
    if (event.more()) (void)monitor_.recv(address, zmq::recv_flags::none);
    if (event.size() < 6) continue;
    std::uint16_t id;
    std::memcpy(&id, event.data(), sizeof id);
    if (id == ZMQ_EVENT_ACCEPTED) {
      stats_.count_transport_event("accepted");
    } else if (id == ZMQ_EVENT_DISCONNECTED) {
      stats_.count_transport_event("disconnected");
      log()->info("a peer connection closed (peer left, or ZeroMQ dropped it for a message over {} bytes)",
                  config_.max_message_bytes);
    }
  }
}

void Receiver::check_timeouts() {
  for (ClientId id : sessions_.expire(Clock::now(), std::chrono::duration<double>(config_.heartbeat_timeout_s))) {
    ++stats_.client(id).timeouts;
    log()->warn("client {} silent for more than {} s: marked disconnected (map kept, it may reconnect)", id,
                config_.heartbeat_timeout_s);
  }
}

void Receiver::log_progress() {
  const auto now = Clock::now();
  const double elapsed = std::chrono::duration<double>(now - last_log_).count();
  last_log_ = now;
  for (const std::string& line : stats_.progress_lines(system_.snapshot(), elapsed)) log()->info("{}", line);
}

void Receiver::send(const std::string& routing_id, const wire::ServerMessage& message) {
  const std::string body = message.SerializeAsString();
  // ROUTER never blocks: a reply to a vanished peer is dropped by ZeroMQ.
  router_.send(zmq::buffer(routing_id), zmq::send_flags::sndmore | zmq::send_flags::dontwait);
  router_.send(zmq::buffer(body), zmq::send_flags::dontwait);
}

void Receiver::reply_error(const std::string& routing_id, ClientId client, std::uint64_t seq, wire::ErrorCode code,
                           const std::string& text, std::uint32_t credits) {
  wire::ServerMessage reply;
  wire::Error* e = reply.mutable_error();
  e->set_client_id(client);
  e->set_seq(seq);
  e->set_code(code);
  e->set_message(text);
  e->set_credits(credits);
  send(routing_id, reply);
}

void Receiver::drop(Session* session, const std::string& routing_id, const std::string& reason, const std::string& what) {
  std::uint64_t count;
  if (session) {
    count = ++stats_.client(session->info.id).dropped[reason];
  } else {
    stats_.count_unattributed(reason);
    count = stats_.unattributed().at(reason);
  }
  if (should_log(count))
    log()->warn("{}: dropped ({}, #{}): {}", source_of(session, routing_id), reason, count, what);
}

}  // namespace cslam::server
