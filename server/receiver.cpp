#include "server/receiver.h"

#include <cerrno>
#include <cstring>
#include <ctime>
#include <fstream>

#include "core/error.h"
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

// Threads of this process (/proc/self/status), for the live thread count.
std::uint64_t process_threads() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("Threads:", 0) == 0) return std::stoull(line.substr(8));
  return 0;
}

// The CURVE key (Z85) the ZAP handler gave this connection as its User-Id; empty without CURVE.
std::string user_id_of(zmq::message_t& message) {
  const char* v = zmq_msg_gets(message.handle(), "User-Id");
  return v ? std::string(v) : std::string();
}

}  // namespace

bool loopback_endpoint(const std::string& endpoint) {
  for (const char* prefix : {"tcp://127.", "tcp://localhost:", "tcp://[::1]:", "ipc://", "inproc://"})
    if (endpoint.rfind(prefix, 0) == 0) return true;
  return false;
}

Receiver::Receiver(zmq::context_t& context, const ReceiverConfig& config, CollaborativeSystem& system,
                   DoneChannel& done, WakePipe& stop)
    : config_(config),
      system_(system),
      done_(done),
      stop_(stop),
      zap_(config.curve ? std::make_unique<auth::ZapHandler>(context, config.curve->clients) : nullptr),
      router_(context, zmq::socket_type::router),
      monitor_(context, zmq::socket_type::pair),
      sessions_(config.max_clients),
      pool_(config.decode_threads, std::max<std::size_t>(16, config.max_clients * config.window),
            [&system](RgbdFrame frame) { return system.submit(std::move(frame)); }),
      reclaimer_(std::make_unique<BackgroundWorker>("reclaim")) {
  router_.set(zmq::sockopt::maxmsgsize, config_.max_message_bytes);
  router_.set(zmq::sockopt::router_handover, 1);
  router_.set(zmq::sockopt::linger, 0);
  if (config_.curve) {
    router_.set(zmq::sockopt::curve_server, 1);
    router_.set(zmq::sockopt::curve_secretkey, config_.curve->server.secret_key);
    router_.set(zmq::sockopt::zap_domain, "cslam");
  }
  const std::string monitor_endpoint =
      "inproc://cslam-router-monitor-" + std::to_string(reinterpret_cast<std::uintptr_t>(this));
  if (zmq_socket_monitor(router_.handle(), monitor_endpoint.c_str(),
                         ZMQ_EVENT_ACCEPTED | ZMQ_EVENT_DISCONNECTED | ZMQ_EVENT_HANDSHAKE_FAILED_AUTH |
                             ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL | ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL) != 0)
    throw zmq::error_t();
  monitor_.connect(monitor_endpoint);
  try {
    router_.bind(config_.bind);
  } catch (const zmq::error_t& e) {  // e.g. the port in use: another server, or --bind
    throw ConfigError("cslam-server: cannot bind --bind " + config_.bind + ": " + e.what());
  }
  endpoint_ = router_.get(zmq::sockopt::last_endpoint);
  start_ = last_log_ = last_publish_ = Clock::now();
  reclaim_hook_ = [this](const ClientInfo& info, int connections) {
    const std::string dir =
        config_.reclaim_dir + "/client_" + std::to_string(info.id) + "-" + std::to_string(connections);
    system_.retire_client(info.id, dir);
  };
  for (const auto& [info, last_seq] : config_.restored_sessions) restore_session({info, last_seq, ""});
  log()->info(
      "listening on {} ({}, window {} frames, max message {} bytes, heartbeat timeout {} s, max {} clients, "
      "{} decode threads)",
      endpoint_,
      config_.curve ? "CURVE, " + std::to_string(config_.curve->clients->size()) + " allowed keys"
                    : std::string("no authentication"),
      config_.window, config_.max_message_bytes, config_.heartbeat_timeout_s, config_.max_clients,
      config_.decode_threads);
}

Receiver::~Receiver() = default;

void Receiver::restore_session(const RestoredSession& session) {
  system_.add_client(session.info);
  sessions_.restore(session, Clock::now());
}

bool Receiver::run() {
  const auto tick = std::chrono::milliseconds(std::max<long>(
      20,
      long(std::min({config_.heartbeat_timeout_s / 4, config_.log_interval_s, config_.publish_interval_s}) * 1000)));
  bool all_done = false;
  for (;;) {
    zmq::pollitem_t items[] = {
        {router_.handle(), 0, ZMQ_POLLIN, 0},      {monitor_.handle(), 0, ZMQ_POLLIN, 0},
        {nullptr, done_.read_fd(), ZMQ_POLLIN, 0}, {nullptr, stop_.read_fd(), ZMQ_POLLIN, 0},
        {nullptr, pool_.read_fd(), ZMQ_POLLIN, 0}, {nullptr, reclaimed_.read_fd(), ZMQ_POLLIN, 0}};
    try {
      zmq::poll(items, 6, tick);
    } catch (const zmq::error_t& e) {
      if (e.num() != EINTR) throw;
      continue;  // a signal: its handler has written to the stop pipe, seen on the next poll
    }
    const Stopwatch busy;
    const double busy_cpu0 = thread_cpu_ms();
    if (items[3].revents & ZMQ_POLLIN) {
      log()->info("stop requested");
      break;
    }
    if (items[4].revents & ZMQ_POLLIN) on_decoded();
    if (items[2].revents & ZMQ_POLLIN) on_frames_done();
    if (items[0].revents & ZMQ_POLLIN) receive_pending();
    if (items[1].revents & ZMQ_POLLIN) on_monitor_event();
    if (items[5].revents & ZMQ_POLLIN) on_reclaimed();
    check_timeouts();
    reclaim_idle();
    if (std::chrono::duration<double>(Clock::now() - last_log_).count() >= config_.log_interval_s) log_progress();
    if (std::chrono::duration<double>(Clock::now() - last_publish_).count() >= config_.publish_interval_s)
      publish_status();
    stats_.note_loop(busy.ms(), thread_cpu_ms() - busy_cpu0);
    if (config_.exit_when_done && sessions_.all_finished(config_.expected_clients)) {
      log()->info("all {} client(s) finished", sessions_.size());
      all_done = true;
      break;
    }
  }
  // Frames already accepted from the network reach SLAM before the caller finishes the system.
  pool_.finish();
  on_decoded();
  publish_status();
  return all_done;
}

void Receiver::receive_pending() {
  // Bounded batch so credits and the stop pipe are serviced even under a flood.
  for (int n = 0; n < 64; ++n) {
    zmq::message_t identity;
    if (!router_.recv(identity, zmq::recv_flags::dontwait)) return;
    const Stopwatch timer;
    const double cpu0 = thread_cpu_ms();
    std::string routing_id(static_cast<const char*>(identity.data()), identity.size());
    std::vector<zmq::message_t> parts;
    while (true) {
      const bool more = parts.empty() ? identity.more() : parts.back().more();
      if (!more) break;
      parts.emplace_back();
      if (!router_.recv(parts.back(), zmq::recv_flags::none)) break;
    }
    Session* session = sessions_.by_routing_id(routing_id);
    const char* kind = "malformed";
    if (parts.size() != 1) {
      drop(session, routing_id, "malformed", "message with " + std::to_string(parts.size()) + " parts");
      reply_error(routing_id, session ? session->info.id : 0, 0, wire::ERROR_MALFORMED,
                  "expected exactly one message part", 0);
    } else {
      kind = handle_message(routing_id, config_.curve ? user_id_of(parts[0]) : std::string(), parts[0]);
    }
    stats_.note_message(kind, timer.ms(), thread_cpu_ms() - cpu0);
  }
}

const char* Receiver::handle_message(const std::string& routing_id, const std::string& key, zmq::message_t& body) {
  Session* session = sessions_.by_routing_id(routing_id);
  stats_.add_bytes(body.size());
  if (session) {
    session->last_seen = Clock::now();
    ++stats_.client(session->info.id).messages;
  }
  wire::ClientMessage message;
  try {
    message = wire::parse_client_message(body.data(), body.size(), source_of(session, routing_id));
  } catch (const wire::WireError& e) {
    drop(session, routing_id, "malformed", e.what());
    reply_error(routing_id, session ? session->info.id : 0, 0, e.code(), e.what(), 0);
    return "malformed";
  }
  switch (message.body_case()) {
    case wire::ClientMessage::kHello:
      on_hello(routing_id, key, message.hello());
      break;
    case wire::ClientMessage::kFrame: {
      auto frame = std::make_unique<wire::RgbdFrame>();
      frame->Swap(message.mutable_frame());  // no copy of the image bytes
      on_frame(routing_id, std::move(frame), body.size());
      break;
    }
    case wire::ClientMessage::kGoodbye:
      on_goodbye(routing_id, message.goodbye());
      break;
    case wire::ClientMessage::kHeartbeat:
      on_heartbeat(routing_id, message.heartbeat());
      break;
    default:
      break;
  }
  return wire::body_name(message);
}

void Receiver::on_hello(const std::string& routing_id, const std::string& key, const wire::Hello& hello) {
  const std::string source = "hello from peer " + routing_id_text(routing_id);
  // Drops are counted against the session only if this connection owns it (a bad hello naming a
  // victim's id is the sender's problem, not the victim's).
  Session* own = sessions_.by_routing_id(routing_id);
  auto refuse = [&](wire::ErrorCode code, const std::string& reason, const std::string& what) {
    drop(own, routing_id, reason, source + ": " + what);
    reply_error(routing_id, ClientId(hello.client_id() <= 0xffff ? hello.client_id() : 0), 0, code, what, 0);
  };
  ClientInfo info;
  try {
    info = wire::from_hello(hello, source, config_.max_pixels);
  } catch (const wire::WireError& e) {
    drop(own, routing_id, error_reason(e.code()), e.what());
    reply_error(routing_id, ClientId(hello.client_id() <= 0xffff ? hello.client_id() : 0), 0, e.code(), e.what(), 0);
    return;
  }
  if (config_.curve && !config_.curve->clients->may_use(key, info.id))
    return refuse(wire::ERROR_NOT_AUTHORIZED, "not_authorized",
                  "this key may not speak for client " + std::to_string(info.id));
  if (reclaiming_.count(info.id))
    return refuse(wire::ERROR_SESSION_BUSY, "session_busy",
                  "client " + std::to_string(info.id) + " is being reclaimed; retry in a moment");
  Admission admission = sessions_.admit(info.id, routing_id, key);
  if (admission == Admission::kNew && sessions_.size() + reclaiming_.size() >= config_.max_clients)
    admission = Admission::kFull;
  switch (admission) {
    case Admission::kFull:
      return refuse(wire::ERROR_TOO_MANY_CLIENTS, "too_many_clients",
                    "the server has " + std::to_string(config_.max_clients) + " sessions (--max-clients)");
    case Admission::kBusy:
      return refuse(wire::ERROR_SESSION_BUSY, "session_busy",
                    "client " + std::to_string(info.id) +
                        " is connected from another peer; a new connection may "
                        "resume it once that one has been silent for " +
                        std::to_string(config_.heartbeat_timeout_s) + " s");
    case Admission::kWrongKey:
      return refuse(wire::ERROR_NOT_AUTHORIZED, "not_authorized",
                    "client " + std::to_string(info.id) + " belongs to another key");
    case Admission::kNew:
    case Admission::kResume:
      break;
  }
  try {
    system_.add_client(info);          // keeps the map of a known client; throws if its camera changed
  } catch (const std::exception& e) {  // std::invalid_argument: camera differs from the registered one
    return refuse(wire::ERROR_BAD_HELLO, "bad_hello", e.what());
  }
  // A known client starting a new recording session (client --new-session): a new map, seqs from 1.
  const bool new_session = hello.new_session() && admission == Admission::kResume;
  auto [session, resumed] = sessions_.open(info, routing_id, Clock::now(), key);
  reclaimed_ids_.erase(info.id);
  if (new_session) {
    system_.start_new_session(info.id);
    session->last_seq = 0;
    session->stamps = {};  // a new recording: a new time base
    resumed = false;
  }
  if (resumed) ++stats_.client(info.id).reconnects;
  ++stats_.client(info.id).messages;
  const std::uint32_t credits = session->in_flight >= config_.window ? 0 : config_.window - session->in_flight;
  log()->info("client {} ('{}') {} from peer {}, camera {}x{}, last seq {}, {} credits", info.id, info.name,
              resumed ? "reconnected" : "connected", routing_id_text(routing_id), info.camera.width, info.camera.height,
              session->last_seq, credits);
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

void Receiver::on_frame(const std::string& routing_id, std::unique_ptr<wire::RgbdFrame> frame, std::size_t bytes) {
  Session* session = sessions_.by_routing_id(routing_id);
  const std::uint64_t seq = frame->seq();
  if (!session) {
    drop(nullptr, routing_id, "not_registered", "frame " + std::to_string(seq) + " before hello");
    reply_error(routing_id, ClientId(frame->client_id()), seq, wire::ERROR_NOT_REGISTERED, "send a hello first", 0);
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
  auto refuse = [&](wire::ErrorCode code, const std::string& what, std::uint32_t credits) {
    drop(session, routing_id, error_reason(code), source + ": " + what);
    reply_error(routing_id, id, seq, code, what, credits);
  };
  if (frame->client_id() != id)
    return refuse(wire::ERROR_WRONG_CLIENT,
                  "client id " + std::to_string(frame->client_id()) + " differs from the hello", 1);
  const std::uint64_t reserved = session->reserved_seq();
  if (seq <= reserved)
    return refuse(wire::ERROR_DUPLICATE_SEQ, "sequence number not above " + std::to_string(reserved), 1);
  if (seq - reserved > config_.max_seq_jump)
    return refuse(
        wire::ERROR_SEQ_JUMP,
        "sequence number more than " + std::to_string(config_.max_seq_jump) + " past " + std::to_string(reserved), 1);
  if (session->in_flight >= config_.window)
    return refuse(wire::ERROR_NO_CREDIT,
                  "more than " + std::to_string(config_.window) + " frames in flight: wait for acks", 0);
  // Cheap checks here (a bad frame is refused at once); decoding happens in the pool.
  try {
    wire::check_frame(*frame, session->info.camera, source);
  } catch (const wire::WireError& e) {
    drop(session, routing_id, error_reason(e.code()), e.what());
    reply_error(routing_id, id, seq, e.code(), e.what(), 1);
    return;
  }
  const double stamp = frame->timestamp();  // finite: check_frame
  const auto now = Clock::now();
  const StampHistory::Verdict verdict = session->stamps.check(stamp, now, config_.timestamp_bound);
  if (!verdict.ok) return refuse(wire::ERROR_TIMESTAMP_JUMP, verdict.message, 1);
  DecodeJob job;
  job.client = id;
  job.seq = seq;
  job.camera = session->info.camera;
  job.source = source;
  job.arrived = now;
  const bool light = !wire::keyframe_eligible(*frame);
  job.frame = std::move(frame);
  if (!pool_.post(std::move(job))) return refuse(wire::ERROR_OVERLOADED, "decode queue full", 1);
  if (light) ++net.frames_light;
  net.raw_bytes += std::uint64_t(session->info.camera.width) * std::uint64_t(session->info.camera.height) * 5u;
  if (verdict.new_epoch) log()->warn("{}: {}", source, verdict.message);
  session->stamps.accept(stamp, now);
  session->decoding.insert(seq);
  ++session->in_flight;
}

void Receiver::on_decoded() {
  for (DecodeResult& r : pool_.drain()) {
    stats_.note_decode(r.decode_ms);
    Session* session = sessions_.by_client(r.client);
    if (!session) continue;  // cannot happen: a session with frames decoding is never reclaimed
    session->decoding.erase(r.seq);
    ClientNetStats& net = stats_.client(r.client);
    if (r.outcome == DecodeResult::Outcome::kSubmitted) {
      session->last_seq = std::max(session->last_seq, r.seq);
      ++net.frames_accepted;
      if (net.decode_dispatch_ms.size() < kMaxTimingSamples) net.decode_dispatch_ms.push_back(r.decode_ms);
      stats_.note_frame(Clock::now());
      continue;
    }
    if (session->in_flight > 0) --session->in_flight;
    const bool shutting = r.outcome == DecodeResult::Outcome::kShuttingDown;
    drop(session, session->routing_id, shutting ? "shutting_down" : error_reason(r.code), r.message);
    reply_error(session->routing_id, r.client, r.seq, r.code, r.message, shutting ? 0 : 1);
  }
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
    reply_error(routing_id, ClientId(heartbeat.client_id()), 0, wire::ERROR_NOT_REGISTERED, "heartbeat before hello",
                0);
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
    // An acknowledged frame was accepted: a Welcome after this Ack must not offer it again, though
    // the decode result that records it too may still be on its way (a seq beyond what this
    // session reserved is an earlier recording's).
    if (done.seq <= session->reserved_seq()) session->last_seq = std::max(session->last_seq, done.seq);
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
      log()->debug("a peer connection closed (peer left, or ZeroMQ dropped it for a message over {} bytes)",
                   config_.max_message_bytes);
    } else if (id == ZMQ_EVENT_HANDSHAKE_FAILED_AUTH) {
      stats_.count_transport_event("auth_failed");
    } else if (id == ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL || id == ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL) {
      stats_.count_transport_event("handshake_failed");
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

void Receiver::reclaim_idle() {
  if (config_.session_ttl_s <= 0) return;
  for (ClientId id : sessions_.reclaimable(Clock::now(), std::chrono::duration<double>(config_.session_ttl_s))) {
    const Session s = *sessions_.by_client(id);
    const ReclaimHook hook = reclaim_hook_;
    DoneChannel* done = &reclaimed_;
    if (!reclaimer_->post([hook, info = s.info, connections = s.connections, done] {
          try {
            hook(info, connections);
          } catch (const std::exception& e) {
            logger("server")->error("reclaiming client {}: {}", info.id, e.what());
          }
          FrameDone reclaimed;
          reclaimed.client = info.id;
          done->push(reclaimed);
        }))
      return;  // the reclaimer is busy: try again on the next tick
    reclaiming_.insert(id);
    sessions_.erase(id);
    stats_.count_reclaimed();
    log()->info("client {} {} for more than {} s: reclaiming its session", id, to_string(s.state),
                config_.session_ttl_s);
  }
}

void Receiver::on_reclaimed() {
  for (const FrameDone& r : reclaimed_.drain()) {
    reclaiming_.erase(r.client);
    reclaimed_ids_.insert(r.client);
    log()->info("client {} reclaimed", r.client);
  }
}

void Receiver::log_progress() {
  const auto now = Clock::now();
  const double elapsed = std::chrono::duration<double>(now - last_log_).count();
  last_log_ = now;
  for (const std::string& line : stats_.progress_lines(system_.snapshot(), elapsed)) log()->info("{}", line);
}

void Receiver::publish_status() {
  last_publish_ = Clock::now();
  if (!board_) return;
  auto status = std::make_shared<http::NetStatus>(stats_.net_status(sessions_));
  status->totals["sessions_reclaiming"] = reclaiming_.size();
  status->reclaimed = reclaimed_ids_;
  status->reclaimed.insert(reclaiming_.begin(), reclaiming_.end());
  status->totals["process_threads"] = process_threads();
  status->totals["decode_queue"] = pool_.queued();
  if (zap_) {
    status->totals["auth_accepted"] = zap_->accepted();
    status->totals["auth_rejected"] = zap_->rejected();
  }
  board_->publish(std::move(status));
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

void Receiver::drop(Session* session, const std::string& routing_id, const std::string& reason,
                    const std::string& what) {
  std::uint64_t count;
  if (session) {
    count = ++stats_.client(session->info.id).dropped[reason];
  } else {
    stats_.count_unattributed(reason);
    count = stats_.unattributed().at(reason);
  }
  if (should_log(count)) log()->warn("{}: dropped ({}, #{}): {}", source_of(session, routing_id), reason, count, what);
}

}  // namespace cslam::server
