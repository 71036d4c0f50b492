#pragma once
// The server's table of client sessions: which ZeroMQ routing id speaks for which client,
// the client's camera, its last accepted sequence number and its frames in flight (credits).
// Owned by the receiving thread only: no locks.
#include <chrono>
#include <map>
#include <optional>
#include <string>

#include "system/rgbd_frame.h"

namespace cslam::server {

using Clock = std::chrono::steady_clock;

enum class SessionState { kActive, kDisconnected, kDone };
const char* to_string(SessionState state);

struct Session {
  ClientInfo info;
  std::string routing_id;        // current ZeroMQ peer identity
  SessionState state = SessionState::kActive;
  std::uint64_t last_seq = 0;    // highest accepted sequence number
  std::uint32_t in_flight = 0;   // frames submitted and not yet consumed by the worker
  Clock::time_point last_seen;
  int connections = 1;           // hellos accepted (1 + reconnects)
};

class SessionTable {
 public:
  // Opens a session for a hello, or resumes the client's session (its map and sequence numbers
  // are kept) and binds it to the new routing id. Returns the session and whether it was resumed.
  std::pair<Session*, bool> open(const ClientInfo& info, const std::string& routing_id, Clock::time_point now);

  // A session restored from a snapshot: known, disconnected, resuming after last_seq at its hello.
  void restore(const ClientInfo& info, std::uint64_t last_seq, Clock::time_point now);

  Session* by_routing_id(const std::string& routing_id);
  Session* by_client(ClientId id);

  // Marks sessions silent for longer than timeout as disconnected; returns their ids.
  std::vector<ClientId> expire(Clock::time_point now, std::chrono::duration<double> timeout);

  // True when at least `expected` clients said goodbye and none is still active (a client that
  // timed out does not hold the run open, but does not count as done either).
  bool all_finished(std::size_t expected) const;
  std::size_t size() const { return sessions_.size(); }
  const std::map<ClientId, Session>& sessions() const { return sessions_; }

 private:
  std::map<ClientId, Session> sessions_;
  std::map<std::string, ClientId> by_routing_;
};

// Printable form of a routing id (ZeroMQ's default ids are 5 binary bytes).
std::string routing_id_text(const std::string& routing_id);

}  // namespace cslam::server
