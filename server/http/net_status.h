#pragma once
// Live network counters of cslam-server, published by the receiving thread a few times per
// second and read by the HTTP layer (/api/status "network", /metrics cslam_net_*): every
// counter of network_stats.json, per client (at most --max-clients sessions) and unattributed.
// A published state is immutable; publish/get swap a shared_ptr under a mutex.
#include <cstdint>
#include <map>
#include <set>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "core/ids.h"

namespace cslam::http {

struct NetClientStatus {
  ClientId id = 0;
  std::string connection;                         // active | disconnected | done
  std::map<std::string, std::uint64_t> counters;  // frames_accepted, bytes_received, messages, ...
  std::map<std::string, std::uint64_t> dropped;   // reason -> count
};

struct NetStatus {
  std::map<std::string, std::uint64_t> totals;        // bytes_received, frames_accepted, sessions, ...
  std::map<std::string, std::uint64_t> unattributed;  // reason -> count (peers without a session)
  std::map<std::string, std::uint64_t> transport;     // accepted / disconnected / auth_failed
  std::map<std::string, double> gauges;               // receive_stall_max_ms, decode_ms_max, ...
  std::map<ClientId, NetClientStatus> clients;        // live sessions only
  // Sessions reclaimed (pipeline freed) or being reclaimed. A client the SLAM side knows but that
  // is in neither `clients` nor here has just said hello (this status predates it).
  std::set<ClientId> reclaimed;
};

class NetStatusBoard {
 public:
  void publish(std::shared_ptr<const NetStatus> status) {
    std::lock_guard<std::mutex> lock(mutex_);
    status_ = std::move(status);
  }
  std::shared_ptr<const NetStatus> get() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return status_;
  }

 private:
  mutable std::mutex mutex_;
  std::shared_ptr<const NetStatus> status_;
};

}  // namespace cslam::http
