#pragma once
// The receiving thread of cslam-server: owns the ZeroMQ ROUTER socket, parses and decodes each
// client message, dispatches frames to CollaborativeSystem (per-client bounded queues and SLAM
// workers), hands flow-control credits back when workers report a frame consumed, and keeps the
// heartbeat bookkeeping. Bad packets are logged with their client, counted and answered with an
// error; nothing a peer sends can stop the loop.
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <zmq.hpp>

#include "core/stopwatch.h"
#include "proto/adapter.h"
#include "server/server_stats.h"
#include "server/session_table.h"
#include "server/wake_pipe.h"
#include "system/collaborative_system.h"

namespace cslam::server {

struct ReceiverConfig {
  std::string bind = "tcp://*:5555";
  // Credit window: frames a client may have in flight. Must be <= SystemConfig::client_queue_capacity
  // so CollaborativeSystem::submit() never blocks this thread.
  std::uint32_t window = 4;
  std::int64_t max_message_bytes = 16 << 20;  // ZMQ_MAXMSGSIZE
  double heartbeat_timeout_s = 5.0;
  double log_interval_s = 5.0;
  std::size_t expected_clients = 1;  // with exit_when_done: clients to wait for
  bool exit_when_done = false;
  // Sessions restored from a snapshot (client, camera, last processed seq): resumed at their hello.
  std::vector<std::pair<ClientInfo, std::uint64_t>> restored_sessions;
};

class Receiver {
 public:
  // Binds the ROUTER socket (throws zmq::error_t on a bad or busy endpoint).
  Receiver(zmq::context_t& context, const ReceiverConfig& config, CollaborativeSystem& system, DoneChannel& done,
           WakePipe& stop);

  // The endpoint actually bound (a "*" port resolved).
  std::string endpoint() const { return endpoint_; }

  // Serves until `stop` is notified or, with exit_when_done, every expected client said goodbye
  // or timed out. Returns true if it ended because all clients were done.
  bool run();

  const ServerStats& stats() const { return stats_; }
  const SessionTable& sessions() const { return sessions_; }

 private:
  void receive_pending();
  void handle(const std::string& routing_id, const zmq::message_t& body);
  void on_hello(const std::string& routing_id, const wire::Hello& hello);
  void on_frame(const std::string& routing_id, const wire::RgbdFrame& frame, std::size_t bytes, const Stopwatch& timer);
  void on_goodbye(const std::string& routing_id, const wire::Goodbye& goodbye);
  void on_heartbeat(const std::string& routing_id, const wire::Heartbeat& heartbeat);
  void on_frames_done();
  void on_monitor_event();
  void check_timeouts();
  void log_progress();

  void send(const std::string& routing_id, const wire::ServerMessage& message);
  void reply_error(const std::string& routing_id, ClientId client, std::uint64_t seq, wire::ErrorCode code,
                   const std::string& message, std::uint32_t credits);
  // Drop accounting with log throttling: a flood of bad packets must not flood the log.
  void drop(Session* session, const std::string& routing_id, const std::string& reason, const std::string& what);

  const ReceiverConfig config_;
  CollaborativeSystem& system_;
  DoneChannel& done_;
  WakePipe& stop_;
  zmq::socket_t router_;
  zmq::socket_t monitor_;
  std::string endpoint_;
  SessionTable sessions_;
  ServerStats stats_;
  Clock::time_point start_, last_log_;
};

}  // namespace cslam::server
