#pragma once
// The receiving thread of cslam-server: owns the ZeroMQ ROUTER socket, parses each client
// message, checks it against the client's session (admission, sequence, credits) and hands frames
// to a small decode pool (decoding and submitting to CollaborativeSystem happen there, never on
// this thread). It hands flow-control credits back when workers report a frame consumed, keeps
// the heartbeat bookkeeping, reclaims idle sessions and publishes live counters for HTTP. Bad
// packets are logged with their client, counted and answered with an error; nothing a peer sends
// can stop the loop. With CURVE keys, a ZAP handler thread authenticates every connection.
#include <cstdint>
#include <functional>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <zmq.hpp>

#include "core/stopwatch.h"
#include "proto/adapter.h"
#include "server/auth/zap_handler.h"
#include "server/background_worker.h"
#include "server/decode_pool.h"
#include "server/http/net_status.h"
#include "server/server_stats.h"
#include "server/session_table.h"
#include "server/wake_pipe.h"
#include "system/collaborative_system.h"

namespace cslam::server {

struct CurveConfig {
  auth::CurveKeyPair server;                         // the server's key pair (--curve-secret)
  std::shared_ptr<const auth::KeyRegistry> clients;  // allowed client keys (--clients-allowed)
};

struct ReceiverConfig {
  std::string bind = "tcp://127.0.0.1:5555";
  // Credit window: frames a client may have in flight. Must be <= SystemConfig::client_queue_capacity
  // so CollaborativeSystem::submit() never blocks a decode thread.
  std::uint32_t window = 4;
  std::int64_t max_message_bytes = 16 << 20;  // ZMQ_MAXMSGSIZE
  double heartbeat_timeout_s = 5.0;
  double log_interval_s = 5.0;
  std::size_t expected_clients = 1;  // with exit_when_done: clients to wait for
  bool exit_when_done = false;
  // Hardening (docs/security.md).
  std::size_t max_clients = 64;                     // sessions (any state) at a time
  std::uint64_t max_pixels = 1920 * 1080;           // largest camera a hello may announce
  std::uint64_t max_seq_jump = 1000000;             // a frame's seq may be at most this far past the last one
  TimestampBound timestamp_bound;                   // forward timestamp jumps (session_table.h)
  double session_ttl_s = 300;                       // reclaim sessions not active for this long (0: never)
  std::size_t decode_threads = 2;                   // decode pool size (shared by all clients)
  std::string reclaim_dir = "cslam-out/reclaimed";  // outputs of reclaimed sessions (default hook)
  std::optional<CurveConfig> curve;                 // set: CURVE server + ZAP handler
  double publish_interval_s = 0.2;                  // live counters for HTTP
  // Sessions restored from a snapshot (client, camera, last processed seq): resumed at their hello.
  std::vector<std::pair<ClientInfo, std::uint64_t>> restored_sessions;
};

// What happens to a reclaimed session's SLAM pipeline. Runs on a background thread, never on the
// receiving thread. The default writes its outputs under reclaim_dir/client_K-N and releases
// it (CollaborativeSystem::retire_client). A persistence store can keep the map instead.
using ReclaimHook = std::function<void(const ClientInfo& client, int connections)>;

// True for tcp://127.0.0.1:..., tcp://localhost:..., tcp://[::1]:..., ipc:// and inproc://.
bool loopback_endpoint(const std::string& endpoint);

class Receiver {
 public:
  // Binds the ROUTER socket (throws zmq::error_t on a bad or busy endpoint).
  Receiver(zmq::context_t& context, const ReceiverConfig& config, CollaborativeSystem& system, DoneChannel& done,
           WakePipe& stop);
  ~Receiver();

  // The endpoint actually bound (a "*" port resolved).
  std::string endpoint() const { return endpoint_; }

  // Serves until `stop` is notified or, with exit_when_done, every expected client said goodbye
  // or timed out. Frames still being decoded are submitted before it returns. Returns true if
  // it ended because all clients were done.
  bool run();

  // Live counters for the HTTP layer (published every publish_interval_s while run() runs).
  void set_status_board(http::NetStatusBoard* board) { board_ = board; }
  // Replaces the default reclaim action (set before run()).
  void set_reclaim_hook(ReclaimHook hook) { reclaim_hook_ = std::move(hook); }
  // A session loaded from a persisted state (before run()); see SessionTable::restore.
  void restore_session(const RestoredSession& session);

  const ServerStats& stats() const { return stats_; }
  const SessionTable& sessions() const { return sessions_; }

 private:
  void receive_pending();
  // Returns the kind of message handled ("hello", "frame", ..., "malformed") for the stall stats.
  const char* handle_message(const std::string& routing_id, const std::string& key, zmq::message_t& body);
  void on_hello(const std::string& routing_id, const std::string& key, const wire::Hello& hello);
  void on_frame(const std::string& routing_id, std::unique_ptr<wire::RgbdFrame> frame, std::size_t bytes);
  void on_goodbye(const std::string& routing_id, const wire::Goodbye& goodbye);
  void on_heartbeat(const std::string& routing_id, const wire::Heartbeat& heartbeat);
  void on_frames_done();
  void on_decoded();
  void on_reclaimed();
  void on_monitor_event();
  void check_timeouts();
  void reclaim_idle();
  void log_progress();
  void publish_status();

  void send(const std::string& routing_id, const wire::ServerMessage& message);
  void reply_error(const std::string& routing_id, ClientId client, std::uint64_t seq, wire::ErrorCode code,
                   const std::string& message, std::uint32_t credits);
  // Drop accounting with log throttling: a flood of bad packets must not flood the log.
  void drop(Session* session, const std::string& routing_id, const std::string& reason, const std::string& what);

  const ReceiverConfig config_;
  CollaborativeSystem& system_;
  DoneChannel& done_;
  WakePipe& stop_;
  std::unique_ptr<auth::ZapHandler> zap_;  // before the router: it must answer its handshakes
  zmq::socket_t router_;
  zmq::socket_t monitor_;
  std::string endpoint_;
  SessionTable sessions_;
  ServerStats stats_;
  DecodePool pool_;
  DoneChannel reclaimed_;             // (client, 0) when a reclaim finished
  std::set<ClientId> reclaiming_;     // ids whose pipeline is being reclaimed (hellos wait)
  std::set<ClientId> reclaimed_ids_;  // ids whose pipeline was reclaimed (until they say hello again)
  ReclaimHook reclaim_hook_;
  std::unique_ptr<BackgroundWorker> reclaimer_;  // last member: joined first
  http::NetStatusBoard* board_ = nullptr;
  Clock::time_point start_, last_log_, last_publish_;
};

}  // namespace cslam::server
