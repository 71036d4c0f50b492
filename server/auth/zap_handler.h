#pragma once
// The ZAP handler (rfc.zeromq.org 27) of cslam-server: one thread answering libzmq's
// authentication requests on inproc://zeromq.zap.01 of the server's context. A CURVE client is
// accepted if its public key is in the allowed set; the key (Z85) becomes the connection's
// User-Id, which the receiver reads from each message to check the ids the key may use.
// Rejections are counted. Stopped through an inproc control socket and joined, never detached.
#include <atomic>
#include <map>
#include <memory>
#include <string>
#include <thread>

#include <zmq.hpp>

#include "proto/keys/curve_keys.h"

namespace cslam::auth {

// Which public key may speak for which client ids (immutable after start; shared read-only).
class KeyRegistry {
 public:
  explicit KeyRegistry(const std::vector<AllowedKey>& keys);
  bool known(const std::string& public_key) const { return keys_.count(public_key) > 0; }
  // True if the key may say hello as `id` (an unbound key may use any id).
  bool may_use(const std::string& public_key, ClientId id) const;
  std::size_t size() const { return keys_.size(); }

 private:
  std::map<std::string, AllowedKey> keys_;
};

class ZapHandler {
 public:
  // Binds inproc://zeromq.zap.01 on `context` and starts the thread. Must exist before the
  // CURVE server socket accepts connections.
  ZapHandler(zmq::context_t& context, std::shared_ptr<const KeyRegistry> registry);
  ~ZapHandler();  // stop()
  ZapHandler(const ZapHandler&) = delete;
  ZapHandler& operator=(const ZapHandler&) = delete;
  void stop();  // idempotent; joins the thread

  std::uint64_t accepted() const { return accepted_; }
  std::uint64_t rejected() const { return rejected_; }

 private:
  void run();
  void answer(const std::vector<zmq::message_t>& request);

  std::shared_ptr<const KeyRegistry> registry_;
  zmq::socket_t zap_, control_in_, control_out_;
  std::atomic<std::uint64_t> accepted_{0}, rejected_{0};
  std::thread thread_;
};

}  // namespace cslam::auth
