#pragma once
// The server's table of client sessions: which ZeroMQ routing id speaks for which client (and,
// with CURVE, with which public key), the client's camera, its last accepted sequence number,
// the frames being decoded and the frames in flight (credits).
// Owned by the receiving thread only: no locks.
//
// Admission rules (docs/security.md):
//  - at most max_clients sessions exist (any state); a hello for a new id beyond that is refused;
//  - a hello for a known id from the connection that owns the session re-opens it;
//  - from another connection it resumes the session only with the same CURVE key, or (without
//    CURVE) only once the old connection is no longer active (timed out or said goodbye).
#include <array>
#include <chrono>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "frame/rgbd_frame.h"

namespace cslam::server {

using Clock = std::chrono::steady_clock;

// Bound on forward timestamp jumps (docs/security.md, "Timestamps"). A frame stamped more than
//   max(min_jump_s, interval_factor x the median of the session's recent frame intervals)
//   + wall_factor x the wall-clock seconds since its last accepted frame
// past that frame is refused (ERROR_TIMESTAMP_JUMP) and the session goes on: one wild stamp no
// longer moves the session's clock (the later, correctly stamped frames were all "not
// increasing" before). The wall-clock term lets a robot that paused for an hour come back with
// stamps an hour later. A genuine jump in the stamps (a replayed recording with a gap) is taken
// after confirm_frames consecutive out-of-bound frames that agree with each other: the last of
// them is accepted and the history restarts from it. min_jump_s <= 0 turns the bound off.
struct TimestampBound {
  double min_jump_s = 10.0;
  double interval_factor = 100.0;
  double wall_factor = 2.0;
  int confirm_frames = 3;
};

// The timestamps a session has accepted: the newest and up to 32 recent intervals.
class StampHistory {
 public:
  struct Verdict {
    bool ok = true;
    bool new_epoch = false;  // accepted as the confirmed start of a new time base
    std::string message;     // why it was refused, or what the new epoch is
  };
  // Whether a frame stamped t (finite) may go on. Refusals are remembered for the confirmation
  // of a genuine jump; nothing else changes until accept().
  Verdict check(double t, Clock::time_point now, const TimestampBound& bound);
  // Records a frame that passed check() and was handed on.
  void accept(double t, Clock::time_point now);
  // The largest forward jump allowed now.
  double allowed_jump(Clock::time_point now, const TimestampBound& bound) const;
  double median_interval() const;  // 0 without intervals
  bool empty() const { return !has_last_; }
  double last() const { return last_; }

 private:
  static constexpr std::size_t kIntervals = 32;
  bool has_last_ = false;
  double last_ = 0;
  Clock::time_point last_wall_{};
  std::array<double, kIntervals> intervals_{};
  std::size_t count_ = 0, next_ = 0;
  int pending_ = 0;          // consecutive out-of-bound frames that agree with each other
  double pending_last_ = 0;  // stamp of the newest of them
  bool epoch_ = false;       // the next accept() starts a new time base
};

enum class SessionState { kActive, kDisconnected, kDone };
const char* to_string(SessionState state);

struct Session {
  ClientInfo info;
  std::string routing_id;  // current ZeroMQ peer identity
  std::string key;         // CURVE public key (Z85) of the connection, empty without CURVE
  SessionState state = SessionState::kActive;
  std::uint64_t last_seq = 0;        // highest accepted sequence number
  StampHistory stamps;               // timestamps of the frames handed on (forward-jump bound)
  std::set<std::uint64_t> decoding;  // seqs handed to the decode pool, result not back yet
  std::uint32_t in_flight = 0;       // frames reserved (decoding or queued) and not yet consumed
  Clock::time_point last_seen;
  int connections = 1;    // hellos accepted (1 + reconnects)
  bool restored = false;  // loaded from a persisted state, no connection yet

  // The highest seq this session has accepted or is decoding: the next frame must be above it.
  std::uint64_t reserved_seq() const { return decoding.empty() ? last_seq : std::max(last_seq, *decoding.rbegin()); }
  bool idle() const { return in_flight == 0 && decoding.empty(); }
};

enum class Admission {
  kNew,       // a new session
  kResume,    // an existing session, bound to this connection from now on
  kBusy,      // the session is live on another connection (no CURVE)
  kWrongKey,  // the session belongs to another CURVE key
  kFull,      // max_clients sessions exist
};
const char* to_string(Admission admission);

// A session known before any connection (e.g. loaded from a persisted state): it starts
// disconnected, so its client may resume it (Welcome.last_seq = last_seq).
struct RestoredSession {
  ClientInfo info;
  std::uint64_t last_seq = 0;
  std::string key;  // CURVE key that owned it; empty: any key bound to the id may resume it
};

class SessionTable {
 public:
  explicit SessionTable(std::size_t max_clients = 64) : max_clients_(max_clients) {}

  // What a hello for `id` from this connection (and key) would get; changes nothing.
  Admission admit(ClientId id, const std::string& routing_id, const std::string& key) const;

  // Opens a session for a hello, or resumes the client's session (its map and sequence numbers
  // are kept) and binds it to the new routing id. Call only after admit() said kNew or kResume.
  // Returns the session and whether it was resumed.
  std::pair<Session*, bool> open(const ClientInfo& info, const std::string& routing_id, Clock::time_point now,
                                 const std::string& key = "");

  // Inserts a session loaded from a persisted state (disconnected until its client says hello).
  // Throws std::invalid_argument if the id is already in the table or the table is full.
  Session& restore(const RestoredSession& restored, Clock::time_point now);

  // A session restored from a snapshot: known, disconnected, resuming after last_seq at its hello.
  void restore(const ClientInfo& info, std::uint64_t last_seq, Clock::time_point now);

  Session* by_routing_id(const std::string& routing_id);
  Session* by_client(ClientId id);

  // Marks sessions silent for longer than timeout as disconnected; returns their ids.
  std::vector<ClientId> expire(Clock::time_point now, std::chrono::duration<double> timeout);

  // Sessions not active (disconnected or done) for longer than ttl, with nothing in flight:
  // candidates for reclaiming their SLAM pipeline.
  std::vector<ClientId> reclaimable(Clock::time_point now, std::chrono::duration<double> ttl) const;
  // Removes a session (after its pipeline was reclaimed). A session that said goodbye still
  // counts for all_finished().
  void erase(ClientId id);

  // True when at least `expected` clients said goodbye and none is still active (a client that
  // timed out does not hold the run open, but does not count as done either).
  bool all_finished(std::size_t expected) const;
  std::size_t size() const { return sessions_.size(); }
  std::size_t max_clients() const { return max_clients_; }
  const std::map<ClientId, Session>& sessions() const { return sessions_; }

 private:
  std::size_t max_clients_;
  std::map<ClientId, Session> sessions_;
  std::map<std::string, ClientId> by_routing_;
  std::size_t erased_done_ = 0;
};

// Printable form of a routing id (ZeroMQ's default ids are 5 binary bytes).
std::string routing_id_text(const std::string& routing_id);

}  // namespace cslam::server
