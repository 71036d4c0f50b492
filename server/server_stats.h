#pragma once
// Network-side statistics of cslam-server: per-client frames accepted/dropped (by reason), bytes,
// decode+dispatch times; packets that could not be attributed to a client. Owned by the receiving
// thread; logged periodically and written to network_stats.json at the end.
#include <chrono>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/ids.h"
#include "server/http/net_status.h"
#include "system/collaborative_system.h"

namespace cslam::server {

class SessionTable;

// Timing samples kept per client (about 8 MB; 9 hours at 30 Hz), later frames are not timed.
constexpr std::size_t kMaxTimingSamples = 1000000;

struct ClientNetStats {
  std::uint64_t frames_accepted = 0, bytes_received = 0, messages = 0;
  // Frames handed to decoding: a lean stream's light frames (H.264 colour, subsampled or no
  // depth), and the bytes all frames' images would take raw (BGR8 + depth16): the ratio.
  std::uint64_t frames_light = 0, raw_bytes = 0;
  std::uint64_t heartbeats = 0, reconnects = 0, timeouts = 0, goodbyes = 0;
  std::map<std::string, std::uint64_t> dropped;  // reason -> count (decode errors, duplicates, ...)
  std::vector<double> decode_dispatch_ms;        // per accepted frame: parse + decode + submit
  std::uint64_t dropped_total() const;
};

class ServerStats {
 public:
  ClientNetStats& client(ClientId id) { return clients_[id]; }
  // A packet from a peer with no session (random bytes before hello, ...).
  void count_unattributed(const std::string& reason) { ++unattributed_[reason]; }
  // A connection closed by a peer or dropped by ZeroMQ (e.g. a message over ZMQ_MAXMSGSIZE).
  void count_transport_event(const std::string& event) { ++transport_[event]; }
  void add_bytes(std::uint64_t bytes) { total_bytes_ += bytes; }
  // An accepted frame, for the aggregate throughput (first to last accepted frame, all clients).
  void note_frame(std::chrono::steady_clock::time_point now) {
    if (frames_total_++ == 0) first_frame_ = now;
    last_frame_ = now;
  }

  // Receiving-thread timings: one loop iteration's work after poll, one message's handling
  // (parse + checks + hand-off), and a decode on a pool thread (decode + submit).
  // Wall-clock ms (what other clients wait) and the thread's CPU ms (the work itself; the rest
  // is time the thread waited for a core on a loaded machine).
  void note_loop(double ms, double cpu_ms);
  void note_message(const char* kind, double ms, double cpu_ms);
  void note_decode(double ms);
  void count_reclaimed() { ++reclaimed_; }

  // The live counters for HTTP: totals, unattributed, transport events, and per client only the
  // sessions in the table (so labels stay bounded by --max-clients).
  http::NetStatus net_status(const SessionTable& sessions) const;

  // One log line per client since the previous call: frames received/processed/dropped, fps, MB/s.
  std::vector<std::string> progress_lines(const SystemSnapshot& snapshot, double elapsed_s);

  // One line per client over the whole run: totals and average fps / MB/s over wall_s.
  std::vector<std::string> summary_lines(const SystemSnapshot& snapshot, double wall_s) const;

  // Everything as JSON text (written to network_stats.json).
  std::string to_json(const SystemSnapshot& snapshot, double wall_s) const;

  const std::map<ClientId, ClientNetStats>& clients() const { return clients_; }
  const std::map<std::string, std::uint64_t>& unattributed() const { return unattributed_; }
  const std::map<std::string, std::uint64_t>& transport() const { return transport_; }

 private:
  std::map<ClientId, ClientNetStats> clients_;
  std::map<std::string, std::uint64_t> unattributed_, transport_;
  std::uint64_t total_bytes_ = 0, frames_total_ = 0, reclaimed_ = 0;
  // Receive-loop stall bookkeeping (ms): maximum and counts above the 20 ms target.
  double loop_max_ms_ = 0, message_max_ms_ = 0, decode_max_ms_ = 0, loop_max_cpu_ms_ = 0, message_max_cpu_ms_ = 0;
  std::uint64_t loops_over_20ms_ = 0, messages_over_20ms_ = 0, messages_ = 0;
  std::map<std::string, double> message_max_ms_by_kind_, message_max_cpu_ms_by_kind_;
  std::chrono::steady_clock::time_point first_frame_, last_frame_;
  // Counters at the previous progress line, for rates.
  std::map<ClientId, std::pair<std::uint64_t, std::uint64_t>> last_processed_bytes_;
};

}  // namespace cslam::server
