#include "server/auth/zap_handler.h"

#include "core/log.h"
#include "core/thread_priority.h"

namespace cslam::auth {

KeyRegistry::KeyRegistry(const std::vector<AllowedKey>& keys) {
  for (const AllowedKey& k : keys) keys_[k.public_key] = k;
}

bool KeyRegistry::may_use(const std::string& public_key, ClientId id) const {
  auto it = keys_.find(public_key);
  return it != keys_.end() && (it->second.client_ids.empty() || it->second.client_ids.count(id) > 0);
}

ZapHandler::ZapHandler(zmq::context_t& context, std::shared_ptr<const KeyRegistry> registry)
    : registry_(std::move(registry)),
      zap_(context, zmq::socket_type::rep),
      control_in_(context, zmq::socket_type::pair),
      control_out_(context, zmq::socket_type::pair) {
  zap_.set(zmq::sockopt::linger, 0);
  zap_.bind("inproc://zeromq.zap.01");
  const std::string control = "inproc://cslam-zap-control-" + std::to_string(reinterpret_cast<std::uintptr_t>(this));
  control_in_.bind(control);
  control_out_.connect(control);
  thread_ = std::thread([this] { run(); });
}

ZapHandler::~ZapHandler() { stop(); }

void ZapHandler::stop() {
  if (!thread_.joinable()) return;
  control_out_.send(zmq::str_buffer("stop"), zmq::send_flags::none);
  thread_.join();
}

void ZapHandler::run() {
  name_current_thread("zap");
  for (;;) {
    zmq::pollitem_t items[] = {{zap_.handle(), 0, ZMQ_POLLIN, 0}, {control_in_.handle(), 0, ZMQ_POLLIN, 0}};
    try {
      zmq::poll(items, 2, std::chrono::milliseconds(-1));
    } catch (const zmq::error_t& e) {
      if (e.num() == EINTR) continue;
      if (e.num() == ETERM) return;
      throw;
    }
    if (items[1].revents & ZMQ_POLLIN) return;
    if (!(items[0].revents & ZMQ_POLLIN)) continue;
    std::vector<zmq::message_t> request;
    do {
      request.emplace_back();
      if (!zap_.recv(request.back(), zmq::recv_flags::none)) break;
    } while (request.back().more());
    answer(request);
  }
}

void ZapHandler::answer(const std::vector<zmq::message_t>& request) {
  // Request: version, request id, domain, address, identity, mechanism, credentials...
  auto text = [&](std::size_t i) { return i < request.size() ? request[i].to_string() : std::string(); };
  const std::string version = text(0), request_id = text(1), address = text(3), mechanism = text(5);
  std::string status = "400", reason = "unknown key", user_id;
  if (version != "1.0") {
    reason = "bad ZAP version";
  } else if (mechanism != "CURVE" || request.size() < 7 || request[6].size() != 32) {
    reason = "CURVE required";
  } else {
    char z85[41];
    zmq_z85_encode(z85, static_cast<const std::uint8_t*>(request[6].data()), 32);
    if (registry_->known(z85)) {
      status = "200";
      reason = "OK";
      user_id = z85;
    }
  }
  if (status == "200") {
    ++accepted_;
  } else {
    const std::uint64_t n = ++rejected_;
    if (n <= 20 || n % 1000 == 0)
      logger("auth")->warn("refused a {} connection from {} ({}, #{})", mechanism.empty() ? "?" : mechanism, address,
                           reason, n);
  }
  // Reply: version, request id, status code, status text, user id, metadata.
  zap_.send(zmq::buffer(version.empty() ? std::string("1.0") : version), zmq::send_flags::sndmore);
  zap_.send(zmq::buffer(request_id), zmq::send_flags::sndmore);
  zap_.send(zmq::buffer(status), zmq::send_flags::sndmore);
  zap_.send(zmq::buffer(reason), zmq::send_flags::sndmore);
  zap_.send(zmq::buffer(user_id), zmq::send_flags::sndmore);
  zap_.send(zmq::str_buffer(""), zmq::send_flags::none);
}

}  // namespace cslam::auth
